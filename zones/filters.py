"""Query filters of GET /zone_set: typed, validated, and combined with AND."""

import django_filters as filters
from django.conf import settings

from kit.api.filters import StrictBooleanFilter, StrictFilterSet, ValuesInFilter
from zones.models import ZoneSet


class ZoneSetFilter(StrictFilterSet):
    map_id = filters.CharFilter(help_text="Zone sets of this map.")
    enabled = StrictBooleanFilter(help_text="true: the maps' enabled zone sets; false: the others.")
    names = ValuesInFilter(
        field_name="name",
        help_text=(
            "Zone sets with one of these names; repeat the parameter: ?names=a&names=b (at most "
            f"{settings.API_MAX_FILTER_VALUES} times)."
        ),
    )

    class Meta:
        model = ZoneSet
        fields: list[str] = []
