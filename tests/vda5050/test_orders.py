from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import orjson
import pytest

from tests.vda5050.samples import sample_header
from vda5050.codec import encode
from vda5050.errors import ProtocolError
from vda5050.models import Action, ActionType, BlockingType, OrderContent
from vda5050.orders import (
    DEFAULT_START_DEVIATION_XY,
    OrderKey,
    Pose,
    Waypoint,
    action_order,
    action_parameters,
    cancel_order,
    check_order_graph,
    factsheet_request,
    instant_action,
    instant_actions,
    last_base_node,
    move_order,
    new_action_id,
    order_id,
    order_key,
    order_update,
    route_order,
    start_pause,
    start_teleop,
    state_request,
    stitch,
    stop_pause,
    stop_teleop,
    unstitch,
)

START = Pose(1.0, 1.0, math.pi / 4, "floor1")
WAYPOINTS = [
    Waypoint(2.0, 1.0, 0.0, "floor1"),
    Waypoint(2.0, 3.0, 1.57, "floor1", allowed_deviation_xy=0.0, allowed_deviation_theta=0.3),
    Waypoint(5.0, 3.0, -1.0, "floor2", allowed_deviation_xy=0.5),
]
IDS = {"mission": "m-1", "node_index": 3, "attempt": 0}


def route(waypoints: list[Waypoint] = WAYPOINTS, **kwargs: Any) -> OrderContent:
    return route_order(**IDS, start=START, waypoints=waypoints, **kwargs)


def test_order_id_is_deterministic_per_mission_node_and_attempt() -> None:
    assert order_id("m-1", 3, 0) == "m-1-n3-r0"
    assert len({order_id("m", n, a) for n in range(3) for a in range(3)}) == 9


@pytest.mark.parametrize(("mission", "index", "attempt"), [("a b", 0, 0), ("", 0, 0), ("m/x", 0, 0)])
def test_order_id_refuses_bad_missions(mission: str, index: int, attempt: int) -> None:
    with pytest.raises(ProtocolError):
        order_id(mission, index, attempt)


@pytest.mark.parametrize(("index", "attempt"), [(-1, 0), (0, -1)])
def test_order_id_refuses_negative_numbers(index: int, attempt: int) -> None:
    with pytest.raises(ValueError):
        order_id("m", index, attempt)


@pytest.mark.parametrize(
    ("element_id", "expected"),
    [
        ("m-1-n3-r0", OrderKey("m-1", 3, 0)),
        ("m-1-n3-r0-s4", OrderKey("m-1", 3, 0)),
        ("m-1-n3-r0-e5", OrderKey("m-1", 3, 0)),
        ("m-1-n3-r0-a0", OrderKey("m-1", 3, 0)),
        ("x-n1-r2-n12-r7-s0", OrderKey("x-n1-r2", 12, 7)),
        ("foreign-node-7", None),
        ("m-1-n3-r0-x4", None),
    ],
)
def test_order_key_maps_our_ids_back(element_id: str, expected: OrderKey | None) -> None:
    assert order_key(element_id) == expected


@pytest.mark.parametrize("count", [0, 1, 3])
def test_route_order_shape(count: int) -> None:
    order = route(WAYPOINTS[:count])

    assert check_order_graph(order) == []
    assert (order.order_id, order.order_update_id) == ("m-1-n3-r0", 0)
    assert [n.sequence_id for n in order.nodes] == list(range(0, 2 * count + 1, 2))
    assert [e.sequence_id for e in order.edges] == list(range(1, 2 * count, 2))
    assert [n.node_id for n in order.nodes] == [f"m-1-n3-r0-s{2 * i}" for i in range(count + 1)]
    assert [e.edge_id for e in order.edges] == [f"m-1-n3-r0-e{2 * i + 1}" for i in range(count)]
    assert all(element.released and element.actions == [] for element in [*order.nodes, *order.edges])


def test_route_order_starts_at_the_robot_and_copies_waypoints() -> None:
    order = route()
    start, *targets = [n.node_position for n in order.nodes]

    assert (start.x, start.y, start.map_id, start.theta) == (1.0, 1.0, "floor1", None)
    assert start.allowed_deviation_xy == DEFAULT_START_DEVIATION_XY
    for position, waypoint in zip(targets, WAYPOINTS, strict=True):
        assert (position.x, position.y, position.theta, position.map_id) == (
            waypoint.x,
            waypoint.y,
            waypoint.theta,
            waypoint.map_id,
        )
        assert position.allowed_deviation_xy == waypoint.allowed_deviation_xy
        assert position.allowed_deviation_theta == waypoint.allowed_deviation_theta


@pytest.mark.parametrize(("start_map", "expected"), [("floor1", "floor1"), ("", "floor2")])
def test_start_node_map_falls_back_to_the_first_waypoint(start_map: str, expected: str) -> None:
    order = route_order(
        **IDS, start=Pose(0.0, 0.0, 0.0, start_map), waypoints=[Waypoint(1.0, 0.0, 0.0, "floor2")]
    )

    assert order.nodes[0].node_position.map_id == expected


def test_start_deviation_is_a_parameter() -> None:
    assert route(start_deviation_xy=2.0).nodes[0].node_position.allowed_deviation_xy == 2.0


@pytest.mark.parametrize(
    ("theta", "expected"),
    [
        (0.5, 0.5),
        (math.pi, math.pi),
        (-math.pi, -math.pi),
        (3 * math.pi / 2, -math.pi / 2),
        (-7.0, -7.0 + math.tau),
    ],
)
def test_waypoint_theta_is_normalised(theta: float, expected: float) -> None:
    order = route([Waypoint(0.0, 0.0, theta, "m")])

    assert order.nodes[1].node_position.theta == pytest.approx(expected)
    assert -math.pi <= order.nodes[1].node_position.theta <= math.pi


@pytest.mark.parametrize(
    "kwargs",
    [
        {"allowed_deviation_xy": -0.1},
        {"allowed_deviation_theta": -0.1},
        {"allowed_deviation_theta": 3.5},
        {"x": math.nan},
    ],
)
def test_waypoint_refuses_bad_values(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        Waypoint(**({"x": 0.0, "y": 0.0, "theta": 0.0, "map_id": "m"} | kwargs))


def test_route_order_with_horizon_releases_a_prefix() -> None:
    order = route(WAYPOINTS[:1], horizon=WAYPOINTS[1:])

    assert check_order_graph(order) == []
    assert [n.released for n in order.nodes] == [True, True, False, False]
    assert [e.released for e in order.edges] == [True, False, False]
    assert last_base_node(order) is order.nodes[1]


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"distance": 1.0}, (1.0 + math.sqrt(0.5), 1.0 + math.sqrt(0.5), math.pi / 4)),
        ({"distance": -2.0}, (1.0 - math.sqrt(2), 1.0 - math.sqrt(2), math.pi / 4)),
        ({"rotation": math.pi / 4}, (1.0, 1.0, math.pi / 2)),
        ({"rotation": math.pi}, (1.0, 1.0, -3 * math.pi / 4)),
    ],
)
def test_move_order(kwargs: dict[str, float], expected: tuple[float, float, float]) -> None:
    order = move_order(**IDS, start=START, **kwargs)
    target = order.nodes[-1]

    assert check_order_graph(order) == []
    assert (len(order.nodes), len(order.edges), target.sequence_id) == (2, 1, 2)
    assert (target.node_position.x, target.node_position.y, target.node_position.theta) == pytest.approx(
        expected
    )
    assert target.node_position.map_id == "floor1"


@pytest.mark.parametrize("kwargs", [{}, {"distance": 1.0, "rotation": 1.0}])
def test_move_order_needs_exactly_one_of_distance_and_rotation(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError, match="exactly one"):
        move_order(**IDS, start=START, **kwargs)


PARAMETERS = {
    "count": 3,
    "ratio": 0.5,
    "flag": False,
    "name": "dock-1",
    "pose": {"y": 2, "x": 1.5, "tags": [1, "a", True]},
    "list": [1, 2.5, "x", None, {"b": 1, "a": 2}],
}


def test_action_order_is_one_node_with_one_typed_action() -> None:
    order = action_order(**IDS, start=START, action_type="dock_robot", parameters=PARAMETERS)
    action = order.nodes[0].actions[0]
    wire = orjson.loads(encode(order, sample_header("2.0.0")))["nodes"][0]["actions"][0]

    assert check_order_graph(order) == []
    assert (len(order.nodes), order.edges) == (1, [])
    assert (action.action_type, action.action_id, action.blocking_type) == (
        "dock_robot",
        "m-1-n3-r0-a0",
        "HARD",
    )
    assert {p["key"]: p["value"] for p in wire["actionParameters"]} == PARAMETERS
    assert [p["key"] for p in wire["actionParameters"]] == sorted(PARAMETERS)
    assert type(wire["actionParameters"][0]["value"]) is int  # "count" stays a number


def test_action_order_blocking_type_and_no_parameters() -> None:
    order = action_order(
        **IDS, start=START, action_type="beep", parameters={}, blocking_type=BlockingType.SOFT
    )

    assert order.nodes[0].actions[0].blocking_type == BlockingType.SOFT
    assert order.nodes[0].actions[0].action_parameters is None


@pytest.mark.parametrize("value", [None, math.inf, {"a": math.nan}, object()])
def test_action_parameters_refuse_non_json_values(value: Any) -> None:
    with pytest.raises(ValueError):
        action_parameters({"k": value})


BUILDERS: dict[str, Callable[[], OrderContent]] = {
    "route": route,
    "route with horizon": lambda: route(WAYPOINTS[:1], horizon=WAYPOINTS[1:]),
    "move": lambda: move_order(**IDS, start=START, distance=1.0),
    "action": lambda: action_order(**IDS, start=START, action_type="x", parameters=PARAMETERS),
    "update": lambda: order_update(route(), waypoints=WAYPOINTS),
}


@pytest.mark.parametrize("name", BUILDERS)
def test_building_twice_gives_identical_bytes(name: str) -> None:
    header = sample_header("2.0.0")

    assert encode(BUILDERS[name](), header) == encode(BUILDERS[name](), header)


def test_parameter_key_order_does_not_change_the_bytes() -> None:
    reordered = {key: PARAMETERS[key] for key in reversed(PARAMETERS)}
    reordered["pose"] = {"tags": [1, "a", True], "x": 1.5, "y": 2}
    build = lambda parameters: encode(  # noqa: E731
        action_order(**IDS, start=START, action_type="x", parameters=parameters), sample_header("2.0.0")
    )

    assert build(reordered) == build(PARAMETERS)


def test_order_update_stitches_at_the_decision_point() -> None:
    first = route(WAYPOINTS[:2])
    update = order_update(first, waypoints=WAYPOINTS[2:])

    assert check_order_graph(update) == []
    assert (update.order_id, update.order_update_id) == (first.order_id, 1)
    assert update.nodes[0] == first.nodes[-1]
    assert [n.sequence_id for n in update.nodes] == [4, 6]
    assert [e.sequence_id for e in update.edges] == [5]
    assert update.edges[0].start_node_id == first.nodes[-1].node_id
    assert all(element.released for element in [*update.nodes, *update.edges])


def test_order_updates_keep_ids_unique_across_the_order() -> None:
    first = route(WAYPOINTS[:1])
    second = order_update(first, waypoints=WAYPOINTS[1:2])
    third = order_update(second, waypoints=WAYPOINTS[2:])
    new_nodes = [n.node_id for order in (first, second, third) for n in order.nodes[1:]]
    edges = [e.edge_id for order in (first, second, third) for e in order.edges]

    assert third.order_update_id == 2
    assert len(set(new_nodes)) == len(new_nodes) == 3
    assert len(set(edges)) == len(edges) == 3


def test_order_update_replaces_and_drops_the_horizon() -> None:
    first = route(WAYPOINTS[:1], horizon=WAYPOINTS[1:])
    replaced = order_update(first, waypoints=[], horizon=WAYPOINTS[2:])
    extended = order_update(replaced, waypoints=WAYPOINTS[1:2])

    assert replaced.nodes[0] == first.nodes[1]  # the decision point, not the horizon's last node
    assert [(n.sequence_id, n.released) for n in replaced.nodes] == [(2, True), (4, False)]
    assert replaced.nodes[1].node_position.x == WAYPOINTS[2].x
    assert [(n.sequence_id, n.released) for n in extended.nodes] == [(2, True), (4, True)]
    assert extended.nodes[1].node_position.x == WAYPOINTS[1].x
    assert all(check_order_graph(order) == [] for order in (first, replaced, extended))


def test_order_update_keeps_the_decision_point_content() -> None:
    first = action_order(**IDS, start=START, action_type="x", parameters={"a": 1})
    update = order_update(first, waypoints=WAYPOINTS[:1])

    assert update.nodes[0] == first.nodes[0]
    assert update.nodes[0] is not first.nodes[0]


def test_order_update_names_its_new_elements_after_the_key_given() -> None:
    first = route(WAYPOINTS[:1])
    update = order_update(first, waypoints=WAYPOINTS[1:], ids=order_id("m-1", 4, 0))

    assert update.order_id == first.order_id
    assert update.nodes[0] == first.nodes[-1]  # the decision point keeps its id
    assert [n.node_id for n in update.nodes[1:]] == ["m-1-n4-r0-s4", "m-1-n4-r0-s6"]
    assert [e.edge_id for e in update.edges] == ["m-1-n4-r0-e3", "m-1-n4-r0-e5"]
    assert [order_key(n.node_id).node_index for n in update.nodes] == [3, 4, 4]
    assert check_order_graph(update) == []


def test_stitch_gives_the_order_as_the_robot_holds_it() -> None:
    first = route(WAYPOINTS[:1])
    update = order_update(first, waypoints=WAYPOINTS[1:], ids=order_id("m-1", 4, 0))

    held = stitch(first, update)

    assert (held.order_id, held.order_update_id) == (first.order_id, 1)
    assert held.nodes == first.nodes + update.nodes[1:]
    assert held.edges == first.edges + update.edges
    assert check_order_graph(held) == []


def test_stitch_replaces_the_horizon() -> None:
    first = route(WAYPOINTS[:1], horizon=WAYPOINTS[1:])
    update = order_update(first, waypoints=WAYPOINTS[2:])

    held = stitch(first, update)

    assert [(n.sequence_id, n.released) for n in held.nodes] == [(0, True), (2, True), (4, True)]
    assert held.nodes[2].node_position.x == WAYPOINTS[2].x
    assert check_order_graph(held) == []


def test_stitch_refuses_an_update_that_does_not_start_at_the_decision_point() -> None:
    first = route(WAYPOINTS[:2])
    update = order_update(route(WAYPOINTS[:1]), waypoints=WAYPOINTS[2:])

    with pytest.raises(ValueError, match="decision point"):
        stitch(first, update)


def test_unstitch_gives_back_the_order_and_the_update_as_sent() -> None:
    first = route(WAYPOINTS[:1])
    second = order_update(first, waypoints=WAYPOINTS[1:2], ids=order_id("m-1", 4, 0))
    third = order_update(second, waypoints=WAYPOINTS[2:], ids=order_id("m-1", 5, 0))
    held = stitch(stitch(first, second), third)
    decision_point = held.nodes[2].sequence_id

    before, update = unstitch(stitch(second, third), decision_point)

    assert (before, update) == (second, third)
    assert unstitch(stitch(first, second), first.nodes[-1].sequence_id) == (first, second)
    assert stitch(*unstitch(held, decision_point)) == held


@pytest.mark.parametrize("sequence_id", [3, 8])
def test_unstitch_refuses_a_node_the_order_does_not_have(sequence_id: int) -> None:
    held = stitch(route(WAYPOINTS[:1]), order_update(route(WAYPOINTS[:1]), waypoints=WAYPOINTS[1:]))

    with pytest.raises(ValueError, match="was not extended"):
        unstitch(held, sequence_id)


def test_unstitch_refuses_an_order_never_updated() -> None:
    with pytest.raises(ValueError, match="was not extended"):
        unstitch(route(WAYPOINTS[:2]), 2)


def _valid() -> OrderContent:
    return route(WAYPOINTS[:2])


def _broken(path: str, value: Any) -> OrderContent:
    """A valid 3-node order with one attribute, named by a dotted path, set to ``value``."""
    order = _valid()
    *parents, name = path.split(".")
    target: Any = order
    for part in parents:
        target = target[int(part)] if part.isdigit() else getattr(target, part)
    setattr(target, name, value)
    return order


def _duplicate_action_ids() -> OrderContent:
    order = _valid()
    order.nodes[0].actions = [Action(action_type="t", action_id="dup", blocking_type=BlockingType.NONE)]
    order.edges[1].actions = [Action(action_type="t", action_id="dup", blocking_type=BlockingType.NONE)]
    return order


@pytest.mark.parametrize(
    ("order", "problem"),
    [
        (OrderContent(order_id="o", order_update_id=0, nodes=[], edges=[]), "at least one node"),
        (_broken("edges", []), "0 edges for 3 nodes"),
        (_broken("nodes.0.sequence_id", 1), "nodes[0].sequenceId 1 is odd"),
        (_broken("nodes.2.sequence_id", 6), "nodes[2].sequenceId is 6, expected 4"),
        (_broken("edges.1.sequence_id", 2), "edges[1].sequenceId is 2, expected 3"),
        (_broken("edges.0.start_node_id", "x"), "edges[0].startNodeId is 'x'"),
        (_broken("edges.1.end_node_id", "x"), "edges[1].endNodeId is 'x'"),
        (_broken("nodes.0.released", False), "nodes[0].released must be true"),
        (_broken("edges.0.released", False), "nodes[1].released is true after an unreleased"),
        (_broken("nodes.2.released", False), "edges[1] is released but its end node nodes[2] is not"),
        (_broken("nodes.1.node_id", ""), "nodes[1].nodeId is empty"),
        (_broken("edges.1.edge_id", ""), "edges[1].edgeId is empty"),
        (_duplicate_action_ids(), "actionId 'dup' is not unique"),
    ],
)
def test_check_order_graph_finds_rule_violations(order: OrderContent, problem: str) -> None:
    problems = check_order_graph(order)

    assert any(problem in p for p in problems), problems


def test_check_order_graph_allows_loops_and_updates() -> None:
    loop = _valid()
    loop.nodes[0].node_id = loop.nodes[2].node_id = "home"
    loop.edges[0].start_node_id = loop.edges[1].end_node_id = "home"
    update = order_update(route(WAYPOINTS[:1]), waypoints=WAYPOINTS[1:])

    assert check_order_graph(loop) == []
    assert update.nodes[0].sequence_id == 2
    assert check_order_graph(update) == []


@pytest.mark.parametrize(
    ("builder", "action_type"),
    [
        (cancel_order, ActionType.CANCEL_ORDER),
        (start_pause, ActionType.START_PAUSE),
        (stop_pause, ActionType.STOP_PAUSE),
        (state_request, ActionType.STATE_REQUEST),
        (factsheet_request, ActionType.FACTSHEET_REQUEST),
        (start_teleop, ActionType.START_TELEOP),
        (stop_teleop, ActionType.STOP_TELEOP),
    ],
)
def test_instant_action_builders(builder: Callable[[str], Action], action_type: str) -> None:
    action = builder("id-1")

    assert (action.action_type, action.action_id, action.blocking_type) == (action_type, "id-1", "NONE")
    assert action.action_parameters is None


def test_instant_action_with_parameters() -> None:
    action = instant_action("initPosition", "i1", {"x": 1.0, "mapId": "m"}, BlockingType.HARD)
    message = instant_actions([action, cancel_order("c1")])

    assert [(p.key, p.value) for p in action.action_parameters] == [("mapId", "m"), ("x", 1.0)]
    assert [a.action_id for a in message.actions] == ["i1", "c1"]


def test_new_action_id_is_unique_and_prefixed() -> None:
    ids = {new_action_id("cancel") for _ in range(100)}

    assert len(ids) == 100
    assert all(i.startswith("cancel-") for i in ids)
    with pytest.raises(ProtocolError):
        new_action_id("bad prefix")
