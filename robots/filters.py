"""Query filters of GET /robot: typed, validated, and combined with AND."""

import django_filters as filters
from django.conf import settings
from django.db.models import QuerySet

from kit.api.filters import FloatFilter, StrictBooleanFilter, StrictFilterSet, ValuesInFilter
from robots.choices import AgvClass, RobotState
from robots.models import Robot

# The README's robot types (reference 3.2.0) and the agv_class each stands for.
LEGACY_ROBOT_TYPES = {"ARM": AgvClass.FORKLIFT, "AMR": AgvClass.CARRIER}


class RobotFilter(StrictFilterSet):
    min_battery = FloatFilter(
        field_name="battery_level",
        lookup_expr="gte",
        help_text="Robots whose battery_level is >= this.",
    )
    max_battery = FloatFilter(
        field_name="battery_level",
        lookup_expr="lte",
        help_text="Robots whose battery_level is <= this.",
    )
    state = filters.ChoiceFilter(choices=RobotState.choices, help_text="Robots in this state.")
    online = StrictBooleanFilter(help_text="true: robots that are connected; false: robots that are not.")
    position_initialized = StrictBooleanFilter(help_text="Robots whose position is (or is not) initialized.")
    names = ValuesInFilter(
        field_name="name",
        help_text=(
            "Robots with one of these names; repeat the parameter: ?names=a&names=b (at most "
            f"{settings.API_MAX_FILTER_VALUES} times)."
        ),
    )
    robot_type = filters.ChoiceFilter(
        choices=[*AgvClass.choices, *((legacy, legacy) for legacy in LEGACY_ROBOT_TYPES)],
        method="filter_robot_type",
        help_text=(
            "Robots whose factsheet agv_class is this. The README's ARM and AMR mean FORKLIFT and CARRIER."
        ),
    )

    class Meta:
        model = Robot
        fields: list[str] = []

    def filter_robot_type(self, queryset: QuerySet[Robot], name: str, value: str) -> QuerySet[Robot]:
        return queryset.filter(agv_class=LEGACY_ROBOT_TYPES.get(value, value))
