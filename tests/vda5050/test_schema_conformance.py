"""Everything the package builds validates against the official schemas of 2.0.0, 2.1.0 and 3.0.0."""

from __future__ import annotations

import math
from collections.abc import Callable

import jsonschema
import orjson
import pytest

from tests.vda5050.samples import full_order, full_state, sample_header
from tests.vda5050.schemas import VERSIONS, validate_message
from vda5050.codec import encode
from vda5050.models import Content
from vda5050.orders import (
    Pose,
    Waypoint,
    action_order,
    cancel_order,
    factsheet_request,
    instant_action,
    instant_actions,
    move_order,
    new_action_id,
    order_update,
    route_order,
    start_pause,
    start_teleop,
    state_request,
    stop_pause,
    stop_teleop,
)

IDS = {"mission": "mission-7", "node_index": 2, "attempt": 1}
START = Pose(0.5, -1.0, 3.0, "")
WAYPOINTS = [Waypoint(1.0, 2.0, 3.1, "map"), Waypoint(4.0, 2.0, -3.1, "map", 0.0, math.pi)]


def _route():
    return route_order(**IDS, start=START, waypoints=WAYPOINTS[:1], horizon=WAYPOINTS[1:])


BUILT: dict[str, Callable[[], Content]] = {
    "route": lambda: route_order(**IDS, start=START, waypoints=WAYPOINTS),
    "route to nowhere": lambda: route_order(**IDS, start=START, waypoints=[]),
    "route with horizon": _route,
    "move distance": lambda: move_order(**IDS, start=START, distance=2.0),
    "move rotation": lambda: move_order(**IDS, start=START, rotation=1.0),
    "action": lambda: action_order(
        **IDS, start=START, action_type="pick", parameters={"n": 1, "f": 0.5, "b": True, "o": {}, "a": []}
    ),
    "update": lambda: order_update(_route(), waypoints=WAYPOINTS[1:]),
    "update dropping horizon": lambda: order_update(_route(), waypoints=[]),
    "update with horizon only": lambda: order_update(_route(), waypoints=[], horizon=WAYPOINTS),
    # What the dispatch step sends ahead: the next route leaf, its elements named after it, stitched at the
    # last node of a new order and of an earlier update.
    "update sent ahead": lambda: order_update(
        route_order(**IDS, start=START, waypoints=WAYPOINTS[:1]), waypoints=WAYPOINTS, ids="mission-7-n3-r0"
    ),
    "update sent ahead of an update": lambda: order_update(
        order_update(
            route_order(**IDS, start=START, waypoints=WAYPOINTS[:1]),
            waypoints=WAYPOINTS[1:],
            ids="mission-7-n3-r0",
        ),
        waypoints=WAYPOINTS[:1],
        ids="mission-7-n4-r0",
    ),
    "instant actions": lambda: instant_actions(
        [
            builder(new_action_id("ia"))
            for builder in (
                cancel_order,
                start_pause,
                stop_pause,
                state_request,
                factsheet_request,
                start_teleop,
                stop_teleop,
            )
        ]
        + [instant_action("initPosition", "init-1", {"x": 1.0, "y": 2.0, "theta": 0.0, "mapId": "m"})]
    ),
}
TOPIC_OF = {name: "instantActions" if name == "instant actions" else "order" for name in BUILT}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("name", BUILT)
def test_built_messages_validate(name: str, version: str) -> None:
    validate_message(TOPIC_OF[name], version, orjson.loads(encode(BUILT[name](), sample_header(version))))


@pytest.mark.parametrize("version", VERSIONS)
def test_legacy_instant_actions_key_is_not_2x_conformant(version: str) -> None:
    """Guards the validator itself: the 1.1 key must fail (``actions`` is required)."""
    payload = encode(BUILT["instant actions"](), sample_header(version), instant_actions_key="instantActions")

    with pytest.raises(jsonschema.ValidationError, match="'actions' is a required property"):
        validate_message("instantActions", version, orjson.loads(payload))


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize(
    ("topic", "change"),
    [
        ("order", lambda m: m.update(timestamp="2026-11-22 10:00")),
        ("order", lambda m: m.update(timestamp="2026-11-31T10:00:00Z")),
        ("order", lambda m: m["nodes"][0].pop("actions")),
        ("order", lambda m: m["edges"][0].update(released="yes")),
        ("order", lambda m: m["nodes"][0]["actions"][0]["actionParameters"][0].update(value=None)),
        ("state", lambda m: m["actionStates"][0].update(actionStatus="DONE")),
        ("state", lambda m: m.pop("safetyState")),
    ],
)
def test_validator_rejects_broken_messages(
    version: str, topic: str, change: Callable[[dict], object]
) -> None:
    """Guards the validator: it must not pass everything (date-time format checking included)."""
    content = full_order() if topic == "order" else full_state()
    message = orjson.loads(encode(content, sample_header(version)))
    change(message)

    with pytest.raises(jsonschema.ValidationError):
        validate_message(topic, version, message)
