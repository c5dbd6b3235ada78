"""Reads of stations."""

from collections.abc import Mapping
from typing import Any

from django.db.models import QuerySet

from kit.api.errors import QueryValidationError
from kit.api.rows import object_get
from stations.filters import StationFilter
from stations.models import Station


def station_get(*, name: str, to_change: bool = False) -> Station:
    """The station called `name`; a missing one is the reference's 400 (PUT/DELETE wording if `to_change`)."""
    return object_get(Station.objects.all(), alias="station", name=name, to_change=to_change)


def station_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[Station]:
    """Stations by name, narrowed by the GET /station query filters (see StationFilter)."""
    filterset = StationFilter(data=filters or {}, queryset=Station.objects.order_by("name"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def stations_exist() -> bool:
    return Station.objects.exists()
