"""Query filters of GET /station: typed, validated, and combined with AND."""

import django_filters as filters
from django.conf import settings
from django.db.models import Q, QuerySet

from kit.api.filters import StrictFilterSet, ValuesInFilter
from stations.choices import AgvClass, StationKind
from stations.models import Station


class StationFilter(StrictFilterSet):
    kind = filters.ChoiceFilter(choices=StationKind.choices, help_text="Stations of this kind.")
    map_id = filters.CharFilter(field_name="pose_map_id", help_text="Stations on this map.")
    robot_type = filters.ChoiceFilter(
        choices=AgvClass.choices,
        method="filter_robot_type",
        help_text="Stations a robot of this type (factsheet agv_class) may use: those that list it or any.",
    )
    names = ValuesInFilter(
        field_name="name",
        help_text=(
            "Stations with one of these names; repeat the parameter: ?names=a&names=b (at most "
            f"{settings.API_MAX_FILTER_VALUES} times)."
        ),
    )

    class Meta:
        model = Station
        fields: list[str] = []

    def filter_robot_type(self, queryset: QuerySet[Station], name: str, value: str) -> QuerySet[Station]:
        return queryset.filter(Q(robot_types=[]) | Q(robot_types__contains=[value]))
