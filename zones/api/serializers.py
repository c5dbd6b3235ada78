"""Zone set API bodies: the spec a client sends (create; a zone set is immutable, so there is no PUT) and
the zone set every endpoint returns. The zones are VDA 5050 3.0's, in snake_case."""

from collections import Counter
from typing import Any

from rest_framework import serializers
from rest_framework.exceptions import ErrorDetail

from kit.api.fields import (
    JsonBooleanField,
    JsonIntegerField,
    JsonStringField,
    NumberField,
    ObjectNameField,
    validate_free_json,
    validate_int64,
)
from kit.api.serializers import ObjectNameSerializer, SpecSerializer, StrictSerializer
from vda5050.polygons import MIN_VERTICES, polygon_problem
from vda5050.zones import TYPED_FIELDS, ZoneType, fields_of
from zones.choices import (
    BidirectedLimitation,
    DirectedLimitation,
    Lifecycle,
    ReleaseLossBehavior,
    ZoneActionBlockingType,
)
from zones.choices import ZoneType as ZoneTypeChoices
from zones.models import MAX_CAPACITY, MAX_VERTICES, MAX_ZONES

# Our setting where the standard has none: robots a RELEASE zone admits at once.
DEFAULT_CAPACITY = 1


class VertexSerializer(StrictSerializer):
    x = NumberField(help_text="x coordinate in metres.")
    y = NumberField(help_text="y coordinate in metres.")


class ZoneActionSerializer(StrictSerializer):
    """An action of an ACTION zone (VDA 5050 zoneAction)."""

    action_type = JsonStringField(help_text="The actionType, as the robot's factsheet lists it.")
    blocking_type = serializers.ChoiceField(choices=ZoneActionBlockingType.choices)
    description = JsonStringField(required=False, help_text="The actionDescriptor.")
    action_parameters = serializers.DictField(
        required=False,
        validators=[validate_free_json, validate_int64],
        help_text="The actionParameters as a mapping key -> value.",
    )
    retriable = JsonBooleanField(required=False, help_text="May go RETRIABLE when it fails.")


class ZoneSerializer(StrictSerializer):
    """One zone: a polygon (counter-clockwise, not crossing itself) and its type, with the fields its type
    requires and no others."""

    zone_id = ObjectNameField(help_text="Unique within the zone set (the zoneId).")
    zone_type = serializers.ChoiceField(choices=ZoneTypeChoices.choices)
    description = JsonStringField(required=False, help_text="The zoneDescriptor.")
    vertices = serializers.ListField(
        child=VertexSerializer(),
        min_length=MIN_VERTICES,
        max_length=MAX_VERTICES,
        help_text="The polygon, counter-clockwise, at least three vertices, not crossing itself.",
    )
    release_loss_behavior = serializers.ChoiceField(
        choices=ReleaseLossBehavior.choices, required=False, help_text="RELEASE zones, required."
    )
    capacity = JsonIntegerField(
        required=False,
        min_value=1,
        max_value=MAX_CAPACITY,
        help_text=f"RELEASE zones only: robots it admits at once (ours, not VDA 5050's; default "
        f"{DEFAULT_CAPACITY}).",
    )
    maximum_speed = NumberField(required=False, min_value=0.0, help_text="SPEED_LIMIT zones, required (m/s).")
    entry_actions = serializers.ListField(
        child=ZoneActionSerializer(), required=False, help_text="ACTION zones, required (may be empty)."
    )
    during_actions = serializers.ListField(
        child=ZoneActionSerializer(), required=False, help_text="ACTION zones, required (may be empty)."
    )
    exit_actions = serializers.ListField(
        child=ZoneActionSerializer(), required=False, help_text="ACTION zones, required (may be empty)."
    )
    priority_factor = NumberField(
        required=False, min_value=0.0, max_value=1.0, help_text="PRIORITY zones, required (0 to 1)."
    )
    penalty_factor = NumberField(
        required=False, min_value=0.0, max_value=1.0, help_text="PENALTY zones, required (0 to 1)."
    )
    direction = NumberField(required=False, help_text="DIRECTED and BIDIRECTED zones, required (radians).")
    directed_limitation = serializers.ChoiceField(
        choices=DirectedLimitation.choices, required=False, help_text="DIRECTED zones, required."
    )
    bidirected_limitation = serializers.ChoiceField(
        choices=BidirectedLimitation.choices, required=False, help_text="BIDIRECTED zones, required."
    )

    def validate_vertices(self, vertices: list[dict[str, float]]) -> list[dict[str, float]]:
        problem = polygon_problem([(vertex["x"], vertex["y"]) for vertex in vertices])
        if problem is not None:
            raise serializers.ValidationError(problem, code="invalid_polygon")
        return vertices

    def validate(self, zone: dict[str, Any]) -> dict[str, Any]:
        zone_type = zone["zone_type"]
        wanted = set(fields_of(zone_type))
        allowed = wanted | ({"capacity"} if zone_type == ZoneType.RELEASE else set())
        errors = {
            field: [ErrorDetail(f"{zone_type} zones need {field}.", code="required")]
            for field in sorted(wanted - set(zone))
        }
        errors |= {
            field: [ErrorDetail(f"{zone_type} zones take no {field}.", code="not_for_zone_type")]
            for field in sorted((set(zone) & (TYPED_FIELDS | {"capacity"})) - allowed)
        }
        if errors:
            raise serializers.ValidationError(errors)
        if zone_type == ZoneType.RELEASE:
            zone.setdefault("capacity", DEFAULT_CAPACITY)
        zone.setdefault("description", "")
        return zone


class ZoneSetSpecSerializer(SpecSerializer):
    """The content of a zone set, immutable once created."""

    map_id = JsonStringField(help_text="The map the zone set belongs to (mapId).")
    description = JsonStringField(default="", allow_blank=True, help_text="The zoneSetDescriptor.")
    zones = serializers.ListField(
        child=ZoneSerializer(), max_length=MAX_ZONES, help_text="The zones; each zone_id at most once."
    )

    def validate_zones(self, zones: list[dict[str, Any]]) -> list[dict[str, Any]]:
        twice = sorted(
            zone_id for zone_id, count in Counter(z["zone_id"] for z in zones).items() if count > 1
        )
        if twice:
            raise serializers.ValidationError(
                f"Each zone_id at most once: {', '.join(twice)} occur more often.", code="duplicate"
            )
        return zones


class ZoneSetCreateSerializer(ObjectNameSerializer, ZoneSetSpecSerializer):
    """A zone set's content plus its name (the zoneSetId) or name prefix."""


class ZoneGrantRevokeSerializer(StrictSerializer):
    """A grant to take back: the robot and the zone (of this zone set) it holds."""

    robot = ObjectNameField(help_text="The robot holding the grant.")
    zone_id = ObjectNameField(help_text="The RELEASE zone of this zone set it holds.")


# --- what a client gets ---------------------------------------------------------------------------------


class ZoneSetStatusSerializer(serializers.Serializer):
    enabled = serializers.BooleanField(
        help_text="The map's enabled zone set: the one robots get and the dispatcher applies (one per map)."
    )


class ZoneSetSerializer(serializers.Serializer):
    """A zone set: its content, name (the zoneSetId), status and lifecycle."""

    map_id = serializers.CharField()
    description = serializers.CharField()
    zones = ZoneSerializer(many=True)
    name = serializers.CharField()
    status = ZoneSetStatusSerializer(source="*")
    lifecycle = serializers.ChoiceField(choices=Lifecycle.choices)
