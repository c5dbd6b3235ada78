from typing import Any

from django.db import models

from stations.choices import Lifecycle, StationKind

# Robots a station holds at most (a bound of the API, README "Limits").
MAX_CAPACITY = 1000


class Station(models.Model):
    """A place robots go to by themselves: a CHARGER to charge, a PARKING station to wait. Its spec is set
    through the API; its reservations (status) belong to the dispatch core."""

    name = models.CharField(max_length=100, primary_key=True)
    lifecycle = models.CharField(max_length=20, choices=Lifecycle.choices, default=Lifecycle.ALIVE)

    # --- spec ---
    kind = models.CharField(max_length=20, choices=StationKind.choices)
    pose_x = models.FloatField(default=0.0)
    pose_y = models.FloatField(default=0.0)
    pose_theta = models.FloatField(default=0.0)
    # Text: a map id is free text of up to FLEET_API_MAX_TEXT_LENGTH characters, as in mission waypoints.
    pose_map_id = models.TextField(blank=True, default="")
    robot_types = models.JSONField(
        default=list, blank=True, help_text="The robot types (agv_class) it serves; empty: any robot."
    )
    capacity = models.PositiveIntegerField(default=1, help_text="How many robots it holds at once.")

    # --- status ---
    # The robots holding or reserving the station, in the order they got it. On the station's own row, so
    # that a reservation is taken under the station's row lock (never more than `capacity`) and the change
    # feed's image of the row is the whole station.
    reservations = models.JSONField(default=list, blank=True, editable=False)

    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["name"]
        indexes = [models.Index(fields=["kind"], name="station_kind_idx")]
        constraints = [
            models.CheckConstraint(condition=models.Q(capacity__gte=1), name="station_capacity_positive"),
        ]

    def __str__(self) -> str:
        return self.name

    @property
    def pose(self) -> dict[str, Any]:
        return {"x": self.pose_x, "y": self.pose_y, "theta": self.pose_theta, "map_id": self.pose_map_id}
