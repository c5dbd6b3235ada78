from django.conf import settings
from django.db import models

from robots.choices import (
    AgvClass,
    InstantActionsKey,
    Lifecycle,
    MapAction,
    ProtocolVersion,
    RobotState,
    SettingSource,
)


def default_interface_name() -> str:
    return settings.VDA5050_INTERFACE_NAME


def default_manufacturer() -> str:
    return settings.VDA5050_MANUFACTURER


def default_protocol_version() -> str:
    return settings.VDA5050_VERSION


class Robot(models.Model):
    """A VDA 5050 robot: its spec (set through the API) and its status (reported by the robot)."""

    name = models.CharField(max_length=100, primary_key=True)
    lifecycle = models.CharField(max_length=20, choices=Lifecycle.choices, default=Lifecycle.ALIVE)

    # --- spec ---
    labels = models.JSONField(default=list, blank=True)
    battery_critical_level = models.FloatField(default=10.0)
    battery_recommended_minimum = models.FloatField(null=True, blank=True)
    battery_recommended_maximum = models.FloatField(null=True, blank=True)
    heartbeat_timeout = models.FloatField(default=30.0, help_text="Seconds without a state before offline.")
    switch_teleop = models.BooleanField(default=False)

    # --- VDA 5050 identity: topic <interface_name>/v<major>/<manufacturer>/<serial_number>/<topic> ---
    interface_name = models.CharField(max_length=100, default=default_interface_name)
    manufacturer = models.CharField(max_length=100, default=default_manufacturer)
    serial_number = models.CharField(max_length=100)
    protocol_version = models.CharField(
        max_length=10, choices=ProtocolVersion.choices, default=default_protocol_version
    )
    protocol_version_source = models.CharField(
        max_length=10, choices=SettingSource.choices, default=SettingSource.DEFAULT
    )
    instant_actions_key = models.CharField(
        max_length=20, choices=InstantActionsKey.choices, default=InstantActionsKey.ACTIONS
    )
    instant_actions_key_source = models.CharField(
        max_length=10, choices=SettingSource.choices, default=SettingSource.DEFAULT
    )
    compatibility_rules = models.JSONField(
        default=list,
        blank=True,
        help_text="Vehicle compatibility rules applied to the robot: rule, applied_at, reason (README).",
    )
    # The headerId of the next message on each topic the server sends the robot. The step that sends
    # messages raises them in its own transaction, so they survive a Redis restart and follow the order in
    # which the robot's steps committed.
    next_order_header_id = models.BigIntegerField(default=0, db_default=0, editable=False)
    next_instant_actions_header_id = models.BigIntegerField(default=0, db_default=0, editable=False)
    next_zone_set_header_id = models.BigIntegerField(default=0, db_default=0, editable=False)
    next_responses_header_id = models.BigIntegerField(default=0, db_default=0, editable=False)
    # The latest messages sent to the robot (topic, headerId, payload), kept until a later step knows they
    # went out: one killed before publishing leaves no headerId unsent (missions.robot_step._wire_messages).
    outbox = models.JSONField(null=True, blank=True, editable=False)
    # The zone set distribution's moves made and not yet seen done (zoneSetId -> zoneSet, enableZoneSet or
    # deleteZoneSet), and when the last was made (`dispatch.zone_sets`): written only when they change.
    zone_set_moves = models.JSONField(default=dict, db_default={}, blank=True, editable=False)
    zone_set_moved_at = models.DateTimeField(null=True, blank=True, editable=False)

    # --- status ---
    state = models.CharField(max_length=20, choices=RobotState.choices, default=RobotState.IDLE)
    state_since = models.DateTimeField(
        null=True, blank=True, help_text="When the robot's state last changed (assignment: the longest idle)."
    )
    operating_mode = models.CharField(
        max_length=20, blank=True, default="", help_text="The VDA 5050 operatingMode the robot last reported."
    )
    online = models.BooleanField(default=False)
    battery_level = models.FloatField(default=0.0)
    pose_x = models.FloatField(default=0.0)
    pose_y = models.FloatField(default=0.0)
    pose_theta = models.FloatField(default=0.0)
    pose_map_id = models.CharField(max_length=100, blank=True, default="")
    position_initialized = models.BooleanField(default=False)
    software_version = models.JSONField(default=dict, blank=True)
    hardware_version = models.JSONField(default=dict, blank=True)
    agv_class = models.CharField(max_length=20, choices=AgvClass.choices, default=AgvClass.CARRIER)
    speed_max = models.FloatField(default=-1.0)
    supported_zones = models.JSONField(
        default=list,
        blank=True,
        help_text="The zone types the robot's factsheet lists (VDA 5050 3.0 supportedZones): it gets the "
        "zone sets of its maps.",
    )
    factsheet = models.JSONField(
        null=True, blank=True, help_text="The robot's last VDA 5050 factsheet, whole."
    )
    info_messages = models.JSONField(null=True, blank=True)
    errors = models.JSONField(default=dict, blank=True)
    maps = models.JSONField(
        default=list,
        blank=True,
        help_text="The maps the robot reports (VDA 5050 2.1+ state.maps): map_id, map_version, map_status, "
        "map_description.",
    )
    zone_sets = models.JSONField(
        default=list,
        blank=True,
        help_text="The zone sets the robot reports (VDA 5050 3.0 state.zoneSets): map_id, zone_set_id, "
        "zone_set_status.",
    )
    last_state_at = models.DateTimeField(null=True, blank=True)
    # --- charging (the station plan's, `missions.trips`) ---
    charge_requested = models.BooleanField(
        default=False,
        help_text="An operator asked it to charge now (POST /robot/{name}/charge); cleared once it holds a "
        "charger.",
    )
    charging_waiting_reason = models.TextField(
        null=True,
        blank=True,
        help_text="Why the robot, low or asked to charge, has no charging trip (no free charger, its "
        "factsheet lists no startCharging, ...); null otherwise.",
    )
    # --- zone access (the zone plan's, `missions.zone_plan`) ---
    zone_access = models.JSONField(
        default=dict,
        blank=True,
        help_text="The RELEASE zones the robot holds and those it waits for: {held: [{map_id, zone_id}, "
        "...], waiting: [...]}; empty while no map has an enabled RELEASE zone.",
    )

    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["name"]
        indexes = [
            models.Index(fields=["state"], name="robot_state_idx"),
            models.Index(fields=["online"], name="robot_online_idx"),
            models.Index(fields=["battery_level"], name="robot_battery_idx"),
            models.Index(fields=["agv_class"], name="robot_agv_class_idx"),
            models.Index(fields=["lifecycle"], name="robot_lifecycle_idx"),
        ]
        constraints = [
            models.UniqueConstraint(
                fields=["interface_name", "manufacturer", "serial_number"], name="robot_vda_identity_unique"
            ),
        ]

    def __str__(self) -> str:
        return self.name


class InstantAction(models.Model):
    """An instant action for a robot, tracked by actionId until the robot reports it FINISHED or FAILED."""

    action_id = models.CharField(max_length=200, primary_key=True)
    robot = models.ForeignKey(Robot, on_delete=models.CASCADE, related_name="instant_actions")
    action_type = models.CharField(max_length=50)
    mission = models.CharField(max_length=100, null=True, blank=True, help_text="Mission it was sent for.")
    status = models.CharField(
        max_length=20, null=True, blank=True, help_text="Last status the robot reported; empty until it does."
    )
    parameters = models.JSONField(
        null=True, blank=True, help_text="Its actionParameters as a mapping (a map action's mapId, ...)."
    )
    sent_at = models.DateTimeField(null=True, blank=True, help_text="Empty until it is first sent.")
    send_count = models.IntegerField(default=0)
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["created_at"]
        indexes = [models.Index(fields=["robot", "status"], name="instant_action_robot_idx")]

    def __str__(self) -> str:
        return f"{self.action_type} {self.action_id}"


class MapActionManager(models.Manager["RobotMapAction"]):
    def get_queryset(self) -> models.QuerySet["RobotMapAction"]:
        return super().get_queryset().filter(action_type__in=MapAction.values)


class RobotMapAction(InstantAction):
    """The instant actions that manage a robot's maps (downloadMap, enableMap, deleteMap): the admin's view
    of them, where operators ask for new ones too."""

    objects = MapActionManager()

    class Meta:
        proxy = True
        verbose_name = "map action"
        ordering = ["-created_at"]
