"""Zone set bodies the zone tests share: one valid zone of each type, in the API's shape."""

from typing import Any

SQUARE = [{"x": 0.0, "y": 0.0}, {"x": 2.0, "y": 0.0}, {"x": 2.0, "y": 2.0}, {"x": 0.0, "y": 2.0}]
TRIANGLE = [{"x": 5.0, "y": 5.0}, {"x": 7.0, "y": 5.0}, {"x": 6.0, "y": 7.0}]
# Crosses itself: edges 0 and 2 meet in the middle.
BOWTIE = [{"x": 0.0, "y": 0.0}, {"x": 2.0, "y": 2.0}, {"x": 2.0, "y": 0.0}, {"x": 0.0, "y": 2.0}]
ACTION = {"action_type": "beep", "blocking_type": "NONE", "action_parameters": {"volume": 3}}

# One zone of each VDA 5050 3.0 type, with the fields it requires.
ZONES: dict[str, dict[str, Any]] = {
    "BLOCKED": {},
    "LINE_GUIDED": {},
    "RELEASE": {"release_loss_behavior": "STOP"},
    "COORDINATED_REPLANNING": {},
    "SPEED_LIMIT": {"maximum_speed": 0.5},
    "ACTION": {"entry_actions": [ACTION], "during_actions": [], "exit_actions": []},
    "PRIORITY": {"priority_factor": 0.5},
    "PENALTY": {"penalty_factor": 1.0},
    "DIRECTED": {"direction": 1.57, "directed_limitation": "STRICT"},
    "BIDIRECTED": {"direction": 0.0, "bidirected_limitation": "RESTRICTED"},
}


def zone(
    zone_type: str, zone_id: str | None = None, vertices: list[dict] | None = None, **fields: Any
) -> dict:
    return {
        "zone_id": zone_id or zone_type.lower(),
        "zone_type": zone_type,
        "vertices": vertices or SQUARE,
        **ZONES[zone_type],
        **fields,
    }


def zone_set(name: str = "floor1-v1", map_id: str = "map", zones: list[dict] | None = None) -> dict:
    return {"name": name, "map_id": map_id, "zones": [zone("RELEASE", "aisle")] if zones is None else zones}
