from django.db import models

from zones.choices import Lifecycle

# Bounds of the API (README "Limits"): zones per set, vertices per zone (each polygon is checked for
# self-intersection, quadratic in its vertices), robots a RELEASE zone admits at once.
MAX_ZONES = 1000
MAX_VERTICES = 100
MAX_CAPACITY = 1000


class ZoneSet(models.Model):
    """A VDA 5050 3.0 zone set of one map: its zones (polygons with a zone type) are immutable, as the
    standard makes a `zoneSetId`'s content; at most one set per map is enabled."""

    # The zoneSetId.
    name = models.CharField(max_length=100, primary_key=True)
    lifecycle = models.CharField(max_length=20, choices=Lifecycle.choices, default=Lifecycle.ALIVE)

    # --- spec (immutable) ---
    # Text: a map id is free text of up to FLEET_API_MAX_TEXT_LENGTH characters, as in mission waypoints.
    map_id = models.TextField()
    description = models.TextField(blank=True, default="", help_text="The zoneSetDescriptor.")
    zones = models.JSONField(
        default=list,
        blank=True,
        help_text="The zones in the API's shape (zone_id, zone_type, vertices, ...).",
    )

    # --- status ---
    enabled = models.BooleanField(default=False, help_text="The map's enabled zone set (one per map).")

    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["name"]
        indexes = [models.Index(fields=["map_id"], name="zone_set_map_idx")]
        constraints = [
            models.UniqueConstraint(
                fields=["map_id"], condition=models.Q(enabled=True), name="zone_set_one_enabled_per_map"
            ),
        ]

    def __str__(self) -> str:
        return self.name
