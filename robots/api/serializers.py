"""Robot API bodies: the spec a client sends (create, PUT) and the robot object every endpoint returns."""

from collections.abc import Mapping
from typing import Any

from django.conf import settings
from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from kit.api.fields import (
    MAX_SECONDS,
    JsonBooleanField,
    JsonStringField,
    NumberField,
    ObjectNameField,
    validate_positive,
)
from kit.api.serializers import ObjectNameSerializer, Pose2DSerializer, SpecSerializer, StrictSerializer
from robots.choices import (
    AgvClass,
    InstantActionsKey,
    Lifecycle,
    MapAction,
    ProtocolVersion,
    RobotState,
    SettingSource,
    TeleopAction,
)
from robots.models import Robot
from vda5050.models import MapStatus


def _model_default(field: str) -> Any:
    return Robot._meta.get_field(field).get_default()


# --- what a client sends --------------------------------------------------------------------------------


class BatterySpecSerializer(StrictSerializer):
    critical_level = NumberField(
        default=_model_default("battery_critical_level"),
        help_text="Battery level below which the robot takes no mission but its trip to a charger; where "
        "recommended_minimum is null, at or below it an idle robot is sent to charge.",
    )
    recommended_minimum = NumberField(
        allow_null=True,
        default=None,
        help_text="Battery level at or below which an idle robot is sent to the nearest free charger.",
    )
    recommended_maximum = NumberField(
        allow_null=True,
        default=None,
        help_text="Battery level at which a robot charging at a charger is sent stopCharging; null: it "
        "charges until it reports charging ended.",
    )


class Vda5050IdentitySerializer(StrictSerializer):
    """How the robot is reached: topics <interface_name>/v<major>/<manufacturer>/<serial_number>/<topic>."""

    interface_name = ObjectNameField(
        required=False,
        help_text=f"First topic level; default {settings.VDA5050_INTERFACE_NAME!r} (setting).",
    )
    manufacturer = ObjectNameField(
        required=False,
        help_text=f"Default {settings.VDA5050_MANUFACTURER!r} (setting).",
    )
    serial_number = ObjectNameField(
        required=False,
        help_text="Default: the robot's name, as in the reference.",
    )
    version = serializers.ChoiceField(
        choices=ProtocolVersion.choices,
        required=False,
        help_text=(
            "VDA 5050 version the robot speaks. Omitted: the robot's factsheet (or the topic it speaks on) "
            f"tells, until then {settings.VDA5050_VERSION!r} (setting)."
        ),
    )
    instant_actions_key = serializers.ChoiceField(
        choices=InstantActionsKey.choices,
        required=False,
        help_text=(
            "Array key of instantActions: 'actions' (VDA 5050 2.x) or the older 'instantActions'. Omitted: "
            "'actions', switched to 'instantActions' if the robot rejects 'actions' (compatibility rule)."
        ),
    )


class RobotSpecSerializer(SpecSerializer):
    """The whole spec of a robot (PUT replaces it: omitted fields go back to their defaults)."""

    labels = serializers.ListField(
        child=JsonStringField(),
        default=list,
        max_length=settings.API_MAX_LABELS,
        help_text="Labels to group robots by (stored, unused).",
    )
    battery = BatterySpecSerializer(required=False)
    heartbeat_timeout = NumberField(
        default=_model_default("heartbeat_timeout"),
        max_value=MAX_SECONDS,
        validators=[validate_positive],
        help_text="Seconds without a state message before the robot counts as offline.",
    )
    switch_teleop = JsonBooleanField(
        default=_model_default("switch_teleop"),
        help_text="true puts the robot in teleop, false takes it out.",
    )
    vda5050 = Vda5050IdentitySerializer(required=False)


class RobotCreateSerializer(ObjectNameSerializer, RobotSpecSerializer):
    """A robot's spec plus the name (or name prefix) of the new robot."""


class TeleopQuerySerializer(serializers.Serializer):
    params = serializers.ChoiceField(choices=TeleopAction.choices, help_text="START or STOP teleop.")


class MapActionRequestSerializer(StrictSerializer):
    """A map action for the robot (VDA 5050 2.1+): download a map version, enable it, or delete it."""

    action = serializers.ChoiceField(
        choices=MapAction.choices,
        help_text="downloadMap (needs map_download_link), enableMap (other versions of the map_id are "
        "disabled by the robot) or deleteMap.",
    )
    map_id = JsonStringField(help_text="The map's VDA 5050 mapId, as waypoints name it.")
    map_version = JsonStringField(help_text="The map's version.")
    map_download_link = JsonStringField(
        required=False, help_text="downloadMap only, required: where the robot downloads the map from."
    )
    map_hash = JsonStringField(
        required=False, help_text="downloadMap only, optional: hash the robot checks the download against."
    )

    def validate(self, attrs: dict) -> dict:
        """Also shapes the body as `robot_map_action` takes it (its keyword arguments)."""
        attrs["action"] = MapAction(attrs["action"])
        download = attrs["action"] == MapAction.DOWNLOAD
        if download and "map_download_link" not in attrs:
            raise serializers.ValidationError(
                {"map_download_link": "downloadMap needs a map_download_link."}, code="missing"
            )
        extra = [key for key in ("map_download_link", "map_hash") if key in attrs]
        if not download and extra:
            raise serializers.ValidationError(
                {key: f"Only downloadMap takes {key}." for key in extra}, code="extra_forbidden"
            )
        return attrs


# --- what a client gets ---------------------------------------------------------------------------------


class RobotBatterySerializer(serializers.Serializer):
    critical_level = serializers.FloatField(source="battery_critical_level")
    recommended_minimum = serializers.FloatField(source="battery_recommended_minimum", allow_null=True)
    recommended_maximum = serializers.FloatField(source="battery_recommended_maximum", allow_null=True)


class CompatibilityRuleSerializer(serializers.Serializer):
    rule = serializers.CharField(help_text="Name of the rule (README, 'Vehicle compatibility rules').")
    applied_at = serializers.DateTimeField()
    reason = serializers.CharField(help_text="What the robot said that made the rule apply.")


class RobotVda5050Serializer(serializers.Serializer):
    interface_name = serializers.CharField()
    manufacturer = serializers.CharField()
    serial_number = serializers.CharField()
    version = serializers.ChoiceField(source="protocol_version", choices=ProtocolVersion.choices)
    version_source = serializers.ChoiceField(
        source="protocol_version_source",
        choices=SettingSource.choices,
        help_text="OPERATOR (given in the spec), DEFAULT, or LEARNED from the robot's factsheet or topic.",
    )
    instant_actions_key = serializers.ChoiceField(choices=InstantActionsKey.choices)
    instant_actions_key_source = serializers.ChoiceField(
        choices=SettingSource.choices,
        help_text="OPERATOR (given in the spec), DEFAULT, or LEARNED by a compatibility rule.",
    )
    compatibility_rules = CompatibilityRuleSerializer(many=True)


class SoftwareVersionSerializer(serializers.Serializer):
    os = serializers.CharField(default="")
    app = serializers.CharField(default="")


class HardwareVersionSerializer(serializers.Serializer):
    manufacturer = serializers.CharField(default="", help_text="From the robot's state messages.")
    serial_number = serializers.CharField(default="", help_text="From the robot's state messages.")


class FactsheetSerializer(serializers.Serializer):
    agv_class = serializers.ChoiceField(choices=AgvClass.choices, help_text="From the robot's factsheet.")
    speed_max = serializers.FloatField(help_text="From the robot's factsheet; -1 until it has sent one.")
    supported_zones = serializers.ListField(
        child=serializers.CharField(),
        help_text="The zone types the robot's factsheet lists (VDA 5050 3.0 supportedZones); empty without. "
        "A robot with some gets the enabled zone sets of its maps.",
    )


class RobotMapSerializer(serializers.Serializer):
    """A map the robot reports having (VDA 5050 2.1+ state.maps)."""

    map_id = serializers.CharField()
    map_version = serializers.CharField()
    map_status = serializers.ChoiceField(
        choices=list(MapStatus), help_text="At most one version of a map_id is ENABLED."
    )
    map_description = serializers.CharField(allow_null=True)


class RobotZoneSetSerializer(serializers.Serializer):
    """A zone set the robot reports holding (VDA 5050 3.0 state.zoneSets)."""

    map_id = serializers.CharField()
    zone_set_id = serializers.CharField()
    zone_set_status = serializers.ChoiceField(
        choices=list(MapStatus), help_text="At most one zone set of a map_id is ENABLED."
    )


class ZoneRefSerializer(serializers.Serializer):
    """A zone of a map's enabled zone set."""

    map_id = serializers.CharField()
    zone_id = serializers.CharField()


class RobotZoneAccessSerializer(serializers.Serializer):
    """The RELEASE zones the robot holds and waits for, as the zone plan last decided (Zone access)."""

    held = ZoneRefSerializer(
        many=True, help_text="Zones it holds: it is inside, its order's base crosses them, or it asked (3.0)."
    )
    waiting = ZoneRefSerializer(
        many=True,
        help_text="Zones it waits for, all at once, at the edge of its route's next leg; empty if it waits "
        "for none.",
    )

    def to_representation(self, instance: Mapping[str, Any]) -> dict[str, Any]:
        """Stored empty while no map has an enabled RELEASE zone: then it holds and waits for nothing."""
        return super().to_representation({"held": [], "waiting": [], **instance})


class MapActionSerializer(serializers.Serializer):
    """A map action asked of the robot, tracked until the robot reports it FINISHED or FAILED."""

    action_id = serializers.CharField(help_text="The VDA 5050 actionId the robot reports it by.")
    action = serializers.ChoiceField(source="action_type", choices=MapAction.choices)
    parameters = serializers.DictField(
        child=serializers.CharField(), help_text="The actionParameters sent (mapId, mapVersion, ...)."
    )
    status = serializers.CharField(
        allow_null=True,
        help_text="The status the robot last reported (WAITING, INITIALIZING, RUNNING, FINISHED, FAILED, "
        "...); null until it reports one.",
    )
    sent_at = serializers.DateTimeField(allow_null=True, help_text="null until it is first sent.")
    created_at = serializers.DateTimeField()


class RobotMapsSerializer(serializers.Serializer):
    """The robot's maps and the map actions asked of it."""

    maps = RobotMapSerializer(many=True)
    actions = MapActionSerializer(many=True, help_text="Newest first.")


class RobotStatusSerializer(serializers.Serializer):
    """What the robot reports, as the dispatch engine last recorded it."""

    pose = serializers.SerializerMethodField()
    position_initialized = serializers.BooleanField()
    software_version = SoftwareVersionSerializer()
    hardware_version = HardwareVersionSerializer()
    factsheet = FactsheetSerializer(source="*")
    online = serializers.BooleanField()
    battery_level = serializers.FloatField()
    state = serializers.ChoiceField(choices=RobotState.choices)
    state_since = serializers.DateTimeField(
        allow_null=True, help_text="When the state last changed; null before its first change."
    )
    operating_mode = serializers.CharField(
        help_text="The VDA 5050 operatingMode the robot last reported (AUTOMATIC, MANUAL, ...); empty before "
        "its first state. A robot takes no new mission in a mode that takes no orders."
    )
    info_messages = serializers.JSONField(allow_null=True)
    errors = serializers.JSONField()
    maps = RobotMapSerializer(
        many=True, help_text="The maps the robot reports (VDA 5050 2.1+); empty if it reports none."
    )
    zone_sets = RobotZoneSetSerializer(
        many=True, help_text="The zone sets the robot reports (VDA 5050 3.0); empty if it reports none."
    )
    zone_access = RobotZoneAccessSerializer()
    charge_requested = serializers.BooleanField(
        help_text="Asked to charge now (POST /robot/{name}/charge) and not yet holding a charger."
    )
    charging_waiting_reason = serializers.CharField(
        allow_null=True,
        help_text="Why the robot, at or below its recommended minimum or asked to charge, has no charging "
        "trip: no free charger, no charger it may use on its map, its factsheet lists no startCharging, "
        "...; null otherwise.",
    )

    @extend_schema_field(Pose2DSerializer)
    def get_pose(self, robot: Robot) -> dict[str, Any]:
        return Pose2DSerializer(
            {"x": robot.pose_x, "y": robot.pose_y, "theta": robot.pose_theta, "map_id": robot.pose_map_id}
        ).data


class RobotSerializer(serializers.Serializer):
    """A robot: its spec fields, name, status and lifecycle."""

    labels = serializers.ListField(child=serializers.CharField())
    battery = RobotBatterySerializer(source="*")
    heartbeat_timeout = serializers.FloatField(help_text="Seconds.")
    switch_teleop = serializers.BooleanField()
    vda5050 = RobotVda5050Serializer(source="*")
    name = serializers.CharField()
    status = RobotStatusSerializer(source="*")
    lifecycle = serializers.ChoiceField(choices=Lifecycle.choices)
