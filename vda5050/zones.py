"""Zone sets (VDA 5050 3.0, the ``zoneSet`` topic): the zone types and what each type carries, and the
``zoneSet`` message's content from a zone set in the fleet's own (snake_case) shape.

A zone set belongs to one map; its content is immutable per ``zoneSetId``; a robot holds at most one
ENABLED set per map. Only 3.0 robots know zones (2.x has no ``zoneSet`` topic).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import StrEnum
from typing import Any

from vda5050.models import State, ZoneSetContent
from vda5050.versions import V3_0

ZONE_SET_ID = "zoneSetId"  # the parameter of enableZoneSet and deleteZoneSet


class ZoneType(StrEnum):
    BLOCKED = "BLOCKED"
    LINE_GUIDED = "LINE_GUIDED"
    RELEASE = "RELEASE"
    COORDINATED_REPLANNING = "COORDINATED_REPLANNING"
    SPEED_LIMIT = "SPEED_LIMIT"
    ACTION = "ACTION"
    PRIORITY = "PRIORITY"
    PENALTY = "PENALTY"
    DIRECTED = "DIRECTED"
    BIDIRECTED = "BIDIRECTED"


class ReleaseLossBehavior(StrEnum):
    """What a robot does when it loses the release of a RELEASE zone it is in."""

    STOP = "STOP"
    CONTINUE = "CONTINUE"
    EVACUATE = "EVACUATE"


class DirectedLimitation(StrEnum):
    SOFT = "SOFT"
    RESTRICTED = "RESTRICTED"
    STRICT = "STRICT"


class BidirectedLimitation(StrEnum):
    SOFT = "SOFT"
    RESTRICTED = "RESTRICTED"


class ZoneActionBlockingType(StrEnum):
    NONE = "NONE"
    SOFT = "SOFT"
    SINGLE = "SINGLE"
    HARD = "HARD"


# The fields (snake_case) each zone type requires beyond zone_id, zone_type and vertices; no other type
# takes them (the document's table, with main's errata: directedLimitation / bidirectedLimitation).
TYPE_FIELDS: dict[ZoneType, tuple[str, ...]] = {
    ZoneType.RELEASE: ("release_loss_behavior",),
    ZoneType.SPEED_LIMIT: ("maximum_speed",),
    ZoneType.ACTION: ("entry_actions", "during_actions", "exit_actions"),
    ZoneType.PRIORITY: ("priority_factor",),
    ZoneType.PENALTY: ("penalty_factor",),
    ZoneType.DIRECTED: ("direction", "directed_limitation"),
    ZoneType.BIDIRECTED: ("direction", "bidirected_limitation"),
}
TYPED_FIELDS = frozenset(field for fields in TYPE_FIELDS.values() for field in fields)
ACTION_LISTS = ("entry_actions", "during_actions", "exit_actions")


def has_zones(version: str) -> bool:
    """Zones came with 3.0.0."""
    return version == V3_0


def reported_zone_sets(state: State) -> list[dict[str, str]]:
    """The zone sets the robot holds (3.0 ``state.zoneSets``) as the fleet shows them, in its order."""
    return [
        {"map_id": z.map_id, "zone_set_id": z.zone_set_id, "zone_set_status": z.zone_set_status.value}
        for z in state.zone_sets or ()
    ]


def supported_zones(factsheet: Mapping[str, Any] | None) -> list[str]:
    """The zone types a robot's factsheet (as it sent it, 3.0 ``typeSpecification.supportedZones``) lists;
    none for a robot without a factsheet or of 2.x (which knows no zones)."""
    if not factsheet:
        return []
    zones = (factsheet.get("typeSpecification") or {}).get("supportedZones") or []
    return [str(zone_type) for zone_type in zones] if isinstance(zones, list) else []


def zone_set_message(
    *, zone_set_id: str, map_id: str, description: str, zones: Iterable[Mapping[str, Any]]
) -> ZoneSetContent:
    """The ``zoneSet`` message (without header) of a zone set in the API's shape."""
    content = zone_set_content(zone_set_id=zone_set_id, map_id=map_id, description=description, zones=zones)
    return ZoneSetContent.model_validate({"zoneSet": content})


def fields_of(zone_type: str) -> tuple[str, ...]:
    return TYPE_FIELDS.get(ZoneType(zone_type), ())


def zone_set_content(
    *, zone_set_id: str, map_id: str, description: str, zones: Iterable[Mapping[str, Any]]
) -> dict[str, Any]:
    """The ``zoneSet`` object of a ``zoneSet`` message (no header) from a zone set in the API's shape."""
    content: dict[str, Any] = {"mapId": map_id, "zoneSetId": zone_set_id}
    if description:
        content["zoneSetDescriptor"] = description
    content["zones"] = [_zone(zone) for zone in zones]
    return content


def _zone(zone: Mapping[str, Any]) -> dict[str, Any]:
    wire: dict[str, Any] = {"zoneId": zone["zone_id"], "zoneType": zone["zone_type"]}
    if zone.get("description"):
        wire["zoneDescriptor"] = zone["description"]
    wire["vertices"] = [{"x": vertex["x"], "y": vertex["y"]} for vertex in zone["vertices"]]
    for field in fields_of(zone["zone_type"]):
        value = zone[field]
        wire[_camel(field)] = [_action(a) for a in value] if field in ACTION_LISTS else value
    return wire


def _action(action: Mapping[str, Any]) -> dict[str, Any]:
    wire: dict[str, Any] = {"actionType": action["action_type"], "blockingType": action["blocking_type"]}
    if action.get("description"):
        wire["actionDescriptor"] = action["description"]
    parameters = action.get("action_parameters") or {}
    if parameters:
        wire["actionParameters"] = [{"key": key, "value": value} for key, value in parameters.items()]
    if action.get("retriable"):
        wire["retriable"] = True
    return wire


def _camel(snake: str) -> str:
    head, *rest = snake.split("_")
    return head + "".join(word.capitalize() for word in rest)


class RequestType(StrEnum):
    """What a 3.0 robot's zone request (state ``zoneRequests``) asks for."""

    ACCESS = "ACCESS"
    REPLANNING = "REPLANNING"  # COORDINATED_REPLANNING zones'


class RequestStatus(StrEnum):
    """Where a 3.0 robot's zone or edge request stands, as the robot reports it."""

    REQUESTED = "REQUESTED"
    GRANTED = "GRANTED"
    REVOKED = "REVOKED"
    EXPIRED = "EXPIRED"  # its lease ran out: it holds nothing any more


class GrantType(StrEnum):
    """The fleet control's answer to a zone request (the ``responses`` topic)."""

    GRANTED = "GRANTED"
    QUEUED = "QUEUED"
    REVOKED = "REVOKED"
    REJECTED = "REJECTED"
