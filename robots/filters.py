"""Query filters of GET /robot: typed, validated, and combined with AND."""

from typing import Any

import django_filters as filters
from django import forms
from django.conf import settings
from django.db.models import QuerySet

from kit.api.filters import StrictFilterSet
from robots.choices import AgvClass, RobotState
from robots.models import Robot

# The README's robot types (reference 3.2.0) and the agv_class each stands for.
LEGACY_ROBOT_TYPES = {"ARM": AgvClass.FORKLIFT, "AMR": AgvClass.CARRIER}

TRUE_WORDS = frozenset({"true", "1", "yes", "on"})
FALSE_WORDS = frozenset({"false", "0", "no", "off"})


class StrictBooleanField(forms.Field):
    """A query boolean that refuses what it cannot read, where Django's would silently ignore the filter."""

    def to_python(self, value: Any) -> bool | None:
        if value in self.empty_values:
            return None
        word = str(value).strip().lower()
        if word in TRUE_WORDS:
            return True
        if word in FALSE_WORDS:
            return False
        raise forms.ValidationError("Must be true or false.", code="invalid")


class StrictBooleanFilter(filters.BooleanFilter):
    field_class = StrictBooleanField


class AnyValueMultipleField(forms.MultipleChoiceField):
    """A repeated query parameter (`?names=a&names=b`) whose values are not limited to a list of choices,
    at most FLEET_API_MAX_FILTER_VALUES of them."""

    def valid_value(self, value: str) -> bool:
        return True

    def validate(self, value: list[str]) -> None:
        super().validate(value)
        if len(value) > settings.API_MAX_FILTER_VALUES:
            raise forms.ValidationError(
                f"At most {settings.API_MAX_FILTER_VALUES} values, not {len(value)}.", code="max_length"
            )


class ValuesInFilter(filters.MultipleChoiceFilter):
    """Keeps the objects whose field equals one of the repeated parameter's values."""

    field_class = AnyValueMultipleField

    def filter(self, qs: QuerySet, value: list[str]) -> QuerySet:
        return qs.filter(**{f"{self.field_name}__in": value}) if value else qs


class FloatFilter(filters.NumberFilter):
    """A number filter on a float column: finite floats, not Decimals."""

    field_class = forms.FloatField


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
