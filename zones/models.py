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


class ZoneGrant(models.Model):
    """A robot holds a RELEASE zone of its map's enabled zone set (`dispatch.zones.decide`): written by
    the zone plan (`missions.zone_plan.zones_plan_run`) alone. A robot is a name, as a mission names its
    robot: a deleted robot's grants go with the next plan run."""

    map_id = models.TextField()
    zone_id = models.TextField()
    robot = models.CharField(max_length=100)
    granted_at = models.DateTimeField()
    # An operator took it back (`zones.services.zone_grant_revoke`); the next plan run applies that.
    revoked_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["granted_at", "id"]
        indexes = [models.Index(fields=["robot"], name="zone_grant_robot_idx")]
        constraints = [
            models.UniqueConstraint(fields=["map_id", "zone_id", "robot"], name="zone_grant_unique"),
        ]

    def __str__(self) -> str:
        return f"{self.robot} holds {self.map_id}/{self.zone_id}"


class ZoneReach(models.Model):
    """How far a robot's order may reach while RELEASE zones are enabled, and what its 3.0 zone requests
    are answered: the zone plan writes it, the robot's step reads it (one LEFT JOIN on the step's robot
    read) and carries it out. A robot has one while some map has an enabled RELEASE zone: its step then
    releases an order's base only through `release_through` of `order_id` (nothing new of another order).
    """

    robot = models.CharField(max_length=100, primary_key=True)
    # The base of order `order_id` may hold its nodes up to this sequenceId; NULL: no more than it holds.
    order_id = models.TextField(null=True, blank=True)
    release_through = models.IntegerField(null=True, blank=True)
    waiting = models.JSONField(default=list, blank=True, help_text="Zone ids the robot waits for.")
    # The answers to its 3.0 zoneRequests, [requestId, grantType] pairs; `responses_version` counts their
    # changes, `responses_sent` is the version its step last sent on the responses topic (whose headerIds
    # are the robot's, `Robot.next_responses_header_id`).
    responses = models.JSONField(default=list, blank=True)
    responses_version = models.IntegerField(default=0)
    responses_sent = models.IntegerField(default=0)
    updated_at = models.DateTimeField(auto_now=True)

    def __str__(self) -> str:
        return self.robot
