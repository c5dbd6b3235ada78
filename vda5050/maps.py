"""Maps (VDA 5050 2.1+): which maps a robot has enabled, and the instant actions that manage them.

A robot reports the maps it holds in ``state.maps`` (at most one ENABLED version per ``mapId``); the
master must see that the maps an order names are enabled before sending it (2.1 section 6.7), and
manages them with ``downloadMap``, ``enableMap`` and ``deleteMap`` (instant actions, in 2.1.0 and 3.0.0
alike; 2.0.0 has none of this).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from vda5050.errors import ProtocolError
from vda5050.models import ActionType, MapStatus, State
from vda5050.versions import V2_0

MAP_ACTIONS = frozenset({ActionType.DOWNLOAD_MAP, ActionType.ENABLE_MAP, ActionType.DELETE_MAP})
MAP_ID = "mapId"
MAP_VERSION = "mapVersion"
MAP_DOWNLOAD_LINK = "mapDownloadLink"
MAP_HASH = "mapHash"


def has_maps(version: str) -> bool:
    """Maps came with 2.1.0."""
    return version != V2_0


def map_action_parameters(
    action_type: str,
    *,
    map_id: str,
    map_version: str,
    map_download_link: str | None = None,
    map_hash: str | None = None,
) -> dict[str, str]:
    """The ``actionParameters`` (as a mapping) of a map action; a download needs its link, the others
    take none of a download's parameters."""
    if action_type not in MAP_ACTIONS:
        raise ProtocolError("actionType", f"{action_type} is not a map action")
    parameters = {MAP_ID: map_id, MAP_VERSION: map_version}
    if action_type == ActionType.DOWNLOAD_MAP:
        if not map_download_link:
            raise ProtocolError(MAP_DOWNLOAD_LINK, "downloadMap needs a mapDownloadLink")
        parameters[MAP_DOWNLOAD_LINK] = map_download_link
        if map_hash:
            parameters[MAP_HASH] = map_hash
    elif map_download_link is not None or map_hash is not None:
        raise ProtocolError("actionParameters", f"{action_type} takes no mapDownloadLink or mapHash")
    return parameters


def enabled_map_ids(state: State) -> frozenset[str] | None:
    """The mapIds the robot has a version of ENABLED; None if it reports no maps at all (2.0, or a stack
    that does not report them), which says nothing about what it can drive on."""
    if not state.maps:
        return None
    return frozenset(m.map_id for m in state.maps if m.map_status == MapStatus.ENABLED)


def maps_not_enabled(state: State, map_ids: Iterable[str]) -> list[str]:
    """The given mapIds (sorted, each once) the robot reports no ENABLED version of; none if it reports
    no maps (see `enabled_map_ids`). An empty mapId names no map."""
    enabled = enabled_map_ids(state)
    if enabled is None:
        return []
    return sorted({map_id for map_id in map_ids if map_id and map_id not in enabled})


def reported_maps(state: State) -> list[dict[str, Any]]:
    """The robot's maps as the fleet shows them (snake_case, in the robot's order)."""
    return [
        {
            "map_id": m.map_id,
            "map_version": m.map_version,
            "map_status": m.map_status.value,
            "map_description": m.map_description,
        }
        for m in state.maps or ()
    ]


def waypoint_map_ids(waypoints: Iterable[Mapping[str, Any]]) -> list[str]:
    """The mapIds route waypoints (in the API's shape) name."""
    return [str(waypoint.get("map_id", "")) for waypoint in waypoints]
