"""Station API bodies: the spec a client sends (create, PUT) and the station object every endpoint returns."""

from typing import Any

from rest_framework import serializers

from kit.api.fields import JsonIntegerField
from kit.api.serializers import ObjectNameSerializer, PoseSerializer, SpecSerializer
from stations.choices import AgvClass, Lifecycle, StationKind
from stations.models import MAX_CAPACITY, Station


def _model_default(field: str) -> Any:
    return Station._meta.get_field(field).get_default()


# --- what a client sends --------------------------------------------------------------------------------


class StationSpecSerializer(SpecSerializer):
    """The whole spec of a station (PUT replaces it: omitted fields go back to their defaults)."""

    kind = serializers.ChoiceField(
        choices=StationKind.choices, help_text="CHARGER: robots charge there; PARKING: robots wait there."
    )
    pose = PoseSerializer(help_text="Where a robot stands at the station.")
    robot_types = serializers.ListField(
        child=serializers.ChoiceField(choices=AgvClass.choices),
        default=list,
        max_length=len(AgvClass.choices),
        help_text="The robot types (factsheet agv_class) it serves; empty: any robot.",
    )
    capacity = JsonIntegerField(
        default=_model_default("capacity"),
        min_value=1,
        max_value=MAX_CAPACITY,
        help_text="How many robots it holds at once (reserved or present).",
    )

    def validate_robot_types(self, robot_types: list[str]) -> list[str]:
        if len(set(robot_types)) != len(robot_types):
            raise serializers.ValidationError("Each robot type at most once.", code="duplicate")
        return robot_types


class StationCreateSerializer(ObjectNameSerializer, StationSpecSerializer):
    """A station's spec plus the name (or name prefix) of the new station."""


# --- what a client gets ---------------------------------------------------------------------------------


class StationStatusSerializer(serializers.Serializer):
    """What the dispatch core keeps of the station."""

    reservations = serializers.ListField(
        child=serializers.CharField(),
        help_text="The robots holding or reserving the station, in the order they got it (at most capacity).",
    )


class StationSerializer(serializers.Serializer):
    """A station: its spec fields, name, status and lifecycle."""

    kind = serializers.ChoiceField(choices=StationKind.choices)
    pose = PoseSerializer()
    robot_types = serializers.ListField(child=serializers.ChoiceField(choices=AgvClass.choices))
    capacity = serializers.IntegerField()
    name = serializers.CharField()
    status = StationStatusSerializer(source="*")
    lifecycle = serializers.ChoiceField(choices=Lifecycle.choices)
