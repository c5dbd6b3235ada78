"""Node builders in the API's shape and the driver that plays a mission through the engine like a worker."""

import copy
from typing import Any

from dispatch.engine import (
    LEAF_KINDS,
    ROOT,
    TickResult,
    Tree,
    initial_node_status,
    parse_tree,
    set_leaf_state,
    tick,
)
from dispatch.vocabulary import DONE_STATES, MissionState

# Short names for the tables of node states in these tests.
PENDING, RUNNING, COMPLETED = MissionState.PENDING, MissionState.RUNNING, MissionState.COMPLETED
CANCELED, FAILED = MissionState.CANCELED, MissionState.FAILED

Status = dict[str, dict[str, Any]]
# One step: leaf results the caller writes, then the expected (mission_state, current_node, some node states).
Step = tuple[dict[str, str], str, int | None, dict[str, str]]


def route(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "route": {"waypoints": [{"x": 1.0, "y": 2.0, "theta": 0.0}]}}


def move(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "move": {"distance": 1.0}}


def action(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {
        "name": name,
        "parent": parent,
        "action": {"action_type": "dummy_action", "action_parameters": {}},
    }


def notify(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "notify": {"url": "http://hooks.invalid/", "json_data": {}}}


def constant(name: str, success: bool, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "constant": {"success": success}}


def sequence(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "sequence": {}}


def selector(name: str, parent: str = ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "selector": {}}


def states(node_status: Status, names: list[str] | dict[str, str]) -> dict[str, str]:
    return {name: node_status[name]["state"] for name in names}


def checked_tick(tree: Tree, node_status: Status) -> TickResult:
    """Tick, and check what must hold after every tick: input untouched, consistent fields, idempotence."""
    before = copy.deepcopy(node_status)
    result = tick(tree, node_status)
    assert node_status == before, "tick modified its input"
    assert result.node_status[ROOT]["state"] == result.mission_state
    if result.mission_state == RUNNING:
        leaf = result.current_leaf
        assert leaf is not None and leaf.kind in LEAF_KINDS
        assert leaf.index == result.current_node
        assert result.node_status[leaf.name]["state"] in (PENDING, RUNNING)
        assert tick(tree, result.node_status) == result, "a second tick with no new result changed something"
    else:
        assert result.mission_state in DONE_STATES
        assert result.current_leaf is None and result.leaf_to_start is None
        again = tick(tree, result.node_status)
        assert (again.node_status, again.mission_state) == (result.node_status, result.mission_state)
    return result


def play(mission_tree: list[dict[str, Any]], steps: list[Step]) -> Status:
    """Apply each step's leaf results, tick, compare, then start the current leaf as a worker would."""
    tree = parse_tree(mission_tree)
    node_status = initial_node_status(tree)
    for number, (results, mission_state, current_node, expected_states) in enumerate(steps):
        for name, state in results.items():
            node_status = set_leaf_state(node_status, name, state)
        result = checked_tick(tree, node_status)
        got = (result.mission_state, result.current_node, states(result.node_status, expected_states))
        assert got == (mission_state, current_node, expected_states), f"step {number}"
        node_status = result.node_status
        if result.leaf_to_start is not None:
            node_status = set_leaf_state(node_status, result.leaf_to_start.name, RUNNING)
    return node_status
