"""Reads of zone sets."""

from collections.abc import Mapping
from typing import Any

from django.db.models import QuerySet

from kit.api.errors import QueryValidationError
from kit.api.rows import object_get
from vda5050.models import ZoneSetContent
from vda5050.zones import zone_set_message
from zones.filters import ZoneSetFilter
from zones.models import ZoneGrant, ZoneSet


def zone_set_get(*, name: str, to_change: bool = False) -> ZoneSet:
    """The zone set called `name`; a missing one is the reference's 400 (DELETE wording if `to_change`)."""
    return object_get(ZoneSet.objects.all(), alias="zone_set", name=name, to_change=to_change)


def zone_set_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[ZoneSet]:
    """Zone sets by name, narrowed by the GET /zone_set query filters (see ZoneSetFilter)."""
    filterset = ZoneSetFilter(data=filters or {}, queryset=ZoneSet.objects.order_by("name"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def zone_sets_enabled() -> bool:
    """Some map has an enabled zone set (beat then runs the zone plan, `missions.zone_plan`)."""
    return ZoneSet.objects.filter(enabled=True).exists()


def zone_set_enabled_on(*, map_id: str) -> ZoneSet | None:
    """The map's enabled zone set, if it has one."""
    return ZoneSet.objects.filter(map_id=map_id, enabled=True).first()


def zone_grants(*, map_id: str) -> QuerySet[ZoneGrant]:
    """The grants of the map's RELEASE zones, in the order they were given."""
    return ZoneGrant.objects.filter(map_id=map_id).order_by("zone_id", "granted_at", "id")


def zone_set_messages(*, names: list[str]) -> list[ZoneSetContent]:
    """The ``zoneSet`` messages (without header) of the named zone sets that exist, in name order."""
    rows = ZoneSet.objects.filter(name__in=names).order_by("name")
    return [
        zone_set_message(zone_set_id=z.name, map_id=z.map_id, description=z.description, zones=z.zones)
        for z in rows.only("name", "map_id", "description", "zones")
    ]
