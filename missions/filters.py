"""Query filters of GET /mission: typed, validated, and combined with AND."""

import django_filters as filters
from django import forms
from django.db.models import F, QuerySet

from kit.api.fields import INT64_MAX
from kit.api.filters import StrictFilterSet
from missions.choices import MissionState
from missions.models import Mission
from robots.filters import StrictBooleanFilter

# most_recent is an SQL LIMIT, a PostgreSQL bigint.
MOST_RECENT_MAX = INT64_MAX


class IntegerFilter(filters.NumberFilter):
    field_class = forms.IntegerField


class MissionFilter(StrictFilterSet):
    state = filters.ChoiceFilter(choices=MissionState.choices, help_text="Missions in this state.")
    started_after = filters.DateTimeFilter(
        field_name="start_timestamp",
        lookup_expr="gte",
        help_text="Missions whose start_timestamp is >= this ISO 8601 time (UTC unless an offset is given).",
    )
    started_before = filters.DateTimeFilter(
        field_name="start_timestamp",
        lookup_expr="lte",
        help_text="Missions whose start_timestamp is <= this ISO 8601 time (UTC unless an offset is given).",
    )
    robot = filters.CharFilter(
        help_text="Missions of the robot with this name (those posted without a robot once bound to it)."
    )
    unbound = StrictBooleanFilter(
        field_name="robot",
        lookup_expr="isnull",
        help_text="true: only missions without a robot (waiting for assignment); false: only those with one.",
    )
    # Declared last on purpose: filters apply in declaration order, and the limit must cut the filtered list.
    most_recent = IntegerFilter(
        method="filter_most_recent",
        min_value=0,
        max_value=MOST_RECENT_MAX,
        help_text=(
            "The N most recent missions by start_timestamp, newest first; missions that have not started "
            "(no start_timestamp) come first, as in the reference."
        ),
    )

    class Meta:
        model = Mission
        fields: list[str] = []

    def filter_most_recent(self, queryset: QuerySet[Mission], name: str, value: int) -> QuerySet[Mission]:
        newest_first = queryset.order_by(F("start_timestamp").desc(nulls_first=True), "-queue_position")
        return newest_first[:value]
