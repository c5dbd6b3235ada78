"""The strict order acceptance of VDA 5050 2.1 (Figure 8): every rejection case, duplicates, stitching."""

from __future__ import annotations

import orjson
import pytest

from tests.simulator.conftest import RobotHarness, action, route
from vda5050.models import Error, Node, NodePosition, OrderContent, StateContent, Trajectory
from vda5050.orders import Waypoint, order_update


def rejection(state: StateContent) -> Error:
    (error,) = state.errors
    assert error.error_level == "WARNING"
    return error


def references(error: Error) -> dict[str, str]:
    return {r.reference_key: r.reference_value for r in error.error_references or ()}


def order_dict(h: RobotHarness, order: OrderContent) -> dict:
    return {**h.header().model_dump(by_alias=True), **order.model_dump(by_alias=True, exclude_none=True)}


def test_malformed_json_is_a_validation_error() -> None:
    h = RobotHarness()
    states = h.states(h.send_order(b"{not json"))
    error = rejection(states[-1])
    assert error.error_type == "validationError"
    assert references(error) == {"topic": "order"}


def test_schema_violation_is_a_validation_error_referencing_the_order() -> None:
    h = RobotHarness()
    body = order_dict(h, route((1, 0)))
    del body["nodes"][1]["released"]
    error = rejection(h.states(h.send_order(orjson.dumps(body)))[-1])
    assert error.error_type == "validationError"
    assert "released" in error.error_description
    assert references(error) == {
        "topic": "order",
        "headerId": str(body["headerId"]),
        "orderId": "m1-n0-r0",
        "orderUpdateId": "0",
    }
    assert h.state.order_id == ""


@pytest.mark.parametrize(
    ("breakage", "expected"),
    [
        (lambda o: o["edges"].pop(), "edges"),
        (lambda o: o["edges"][0].update(sequenceId=7), "sequenceId"),
        (lambda o: o["edges"][0].update(endNodeId="elsewhere"), "endNodeId"),
        (lambda o: o["nodes"][1].update(released=False), "released"),
        (
            lambda o: o["nodes"][1]["actions"].extend(
                [{"actionType": "drop", "actionId": "a", "blockingType": "HARD"}] * 2
            ),
            "not unique",
        ),
    ],
)
def test_graph_rule_violations_are_validation_errors(breakage, expected: str) -> None:
    h = RobotHarness()
    body = order_dict(h, route((1, 0)))
    breakage(body)
    error = rejection(h.states(h.send_order(orjson.dumps(body)))[-1])
    assert error.error_type == "validationError"
    assert expected in error.error_description
    assert references(error)["orderId"] == "m1-n0-r0"


def test_new_order_must_start_at_sequence_id_zero() -> None:
    h = RobotHarness()
    order = route((1, 0))
    for element in [*order.nodes, *order.edges]:
        element.sequence_id += 2
    h.send_order(order)
    assert rejection(h.state).error_type == "validationError"


@pytest.mark.parametrize(
    "header", [{"serial_number": "someone-else"}, {"manufacturer": "OtherCo"}, {"version": "1.1.0"}]
)
def test_order_for_another_robot_or_version_is_rejected(header: dict) -> None:
    h = RobotHarness()
    h.send_order(route((1, 0)), **header)
    assert rejection(h.state).error_type == "validationError"
    assert h.state.order_id == ""


def test_new_order_while_busy_is_rejected_and_the_old_one_goes_on() -> None:
    h = RobotHarness()
    h.send_order(route((5, 0)))
    h.tick(2)
    h.send_order(route((0.5, 0), start=(0.5, 0), mission="other"))
    error = rejection(h.state)
    assert error.error_type == "orderError"
    assert "busy" in error.error_description
    assert references(error)["orderId"] == "other-n0-r0"
    assert h.state.order_id == "m1-n0-r0"
    final = h.run_until(lambda s: not s.node_states)
    assert final.last_node_id == "m1-n0-r0-s2"


def test_an_unfinished_action_keeps_the_robot_busy() -> None:
    h = RobotHarness()
    order = route((0, 0))
    order.nodes[1].actions.append(action("dummy_action", "wait", should_fail=False, time=5))
    h.send_order(order)
    h.run_until(lambda s: not s.node_states)
    h.send_order(route((0, 0), mission="next"))
    assert "busy" in rejection(h.state).error_description


@pytest.mark.parametrize(
    ("start", "map_id"), [((0.6, 0.0), "map"), ((0.0, 0.0), "other_map")], ids=["too far", "other map"]
)
def test_first_node_out_of_range_is_rejected(start: tuple[float, float], map_id: str) -> None:
    h = RobotHarness()
    order = route((1, 0), start=start)
    order.nodes[0].node_position.map_id = map_id
    h.send_order(order)
    error = rejection(h.state)
    assert error.error_type == "orderError"
    assert order.nodes[0].node_id in error.error_description
    assert h.state.order_id == ""


def test_first_node_within_its_deviation_is_accepted() -> None:
    h = RobotHarness()
    h.send_order(route((1, 0), start=(0.3, 0.3)))  # Dispatch's start nodes allow 0.5 m
    assert h.state.order_id == "m1-n0-r0" and not h.state.errors


def test_first_node_without_position_must_be_the_last_node() -> None:
    h = RobotHarness()
    h.send_order(route((1, 0)))
    h.run_until(lambda s: not s.node_states)
    follow_up = route((2, 0), start=(1, 0), mission="m2")
    follow_up.nodes[0] = Node(node_id="m1-n0-r0-s2", sequence_id=0, released=True, actions=[])
    follow_up.edges[0].start_node_id = "m1-n0-r0-s2"
    h.send_order(follow_up)
    assert h.state.order_id == "m2-n0-r0" and not h.state.errors
    stranger = route((3, 0), start=(2, 0), mission="m3")
    h.run_until(lambda s: not s.node_states)
    stranger.nodes[0] = Node(node_id="unknown", sequence_id=0, released=True, actions=[])
    stranger.edges[0].start_node_id = "unknown"
    h.send_order(stranger)
    assert rejection(h.state).error_type == "orderError"


def test_unsupported_fields_are_rejected_not_ignored() -> None:
    h = RobotHarness()
    order = route((1, 0))
    order.edges[0].trajectory = Trajectory(degree=1, knot_vector=[0, 0, 1, 1], control_points=[])
    h.send_order(order)
    error = rejection(h.state)
    assert error.error_type == "orderError" and "trajectory" in error.error_description


def test_intermediate_node_without_position_is_rejected() -> None:
    h = RobotHarness()
    order = route((1, 0))
    order.nodes[1].node_position = None
    h.send_order(order)
    assert rejection(h.state).error_type == "orderError"


def test_exact_duplicate_is_discarded_silently() -> None:
    h = RobotHarness()
    order = route((5, 0))
    h.send_order(order)
    h.tick(3)
    assert h.send_order(order) == []  # same orderId and orderUpdateId: no state, no change
    assert h.state.agv_position.x == 0.75 and not h.state.errors


def test_lower_order_update_id_is_an_order_update_error() -> None:
    h = RobotHarness()
    first = route((5, 0))
    update = order_update(first, waypoints=[])  # orderUpdateId 1, just the decision point
    h.send_order(first)
    h.send_order(update)
    assert h.state.order_update_id == 1 and not h.state.errors
    h.send_order(first)
    error = rejection(h.state)
    assert error.error_type == "orderUpdateError"
    assert references(error)["orderUpdateId"] == "0"
    assert h.state.order_update_id == 1


def test_update_must_start_at_the_decision_point() -> None:
    h = RobotHarness()
    first = route((1, 0), (2, 0))
    h.send_order(first)
    # a well-formed update that starts at the first base node instead of the last one
    wrong = first.model_copy(
        update={"order_update_id": 1, "nodes": first.nodes[1:], "edges": first.edges[1:]}
    )
    h.send_order(wrong)
    error = rejection(h.state)
    assert error.error_type == "orderUpdateError"
    assert "decision point" in error.error_description
    assert h.state.order_update_id == 0


def test_update_extends_the_base_while_driving_and_replaces_the_horizon() -> None:
    h = RobotHarness()
    first = route((1, 0), horizon=((9, 9),))
    first.nodes[2].actions.append(action("drop", "horizon-drop"))
    h.send_order(first)
    assert [a.action_id for a in h.state.action_states] == ["horizon-drop"]
    h.tick(2)
    update = order_update(first, waypoints=[waypoint(1, 1)], horizon=[waypoint(1, 2)])
    states = h.states(h.send_order(update))
    assert states and h.state.order_update_id == 1
    assert [(n.sequence_id, n.released) for n in h.state.node_states] == [(2, True), (4, True), (6, False)]
    assert [(e.sequence_id, e.released) for e in h.state.edge_states] == [(1, True), (3, True), (5, False)]
    assert h.state.action_states == []  # the replaced horizon's action is gone
    final = h.run_until(lambda s: s.last_node_sequence_id == 4 and not s.driving)
    assert (final.agv_position.x, final.agv_position.y) == (1.0, 1.0)
    assert final.new_base_request is True


@pytest.mark.parametrize("version", ["2.0.0", "2.1.0", "3.0.0"])
def test_an_update_stitched_before_the_end_of_the_base_is_driven_on_without_stopping(version: str) -> None:
    """What Dispatch does with consecutive route leaves: the robot passes the decision point driving."""
    h = RobotHarness(f"carter01,0,0,0,map,0,80,,,,{version}")
    first = route((1, 0), (2, 0))
    h.send_order(first)
    h.send_order(order_update(first, waypoints=[waypoint(2, 1), waypoint(3, 1)], ids="m1-n1-r0"))
    assert h.state.order_update_id == 1 and not h.state.errors

    states = h.states(h.run(10))
    leaving = next(i for i, s in enumerate(states) if s.last_node_sequence_id >= 4)
    assert all(s.driving for s in states[: leaving + 1] if s.node_states), "stopped on the way"
    assert states[leaving].driving and states[leaving].node_states, "stopped at the decision point"
    final = h.run_until(lambda s: not s.node_states and not s.driving)
    assert (final.last_node_sequence_id, final.agv_position.x, final.agv_position.y) == (8, 3.0, 1.0)


def test_update_after_the_base_is_done_must_start_at_the_last_node() -> None:
    h = RobotHarness()
    first = route((1, 0))
    h.send_order(first)
    h.run_until(lambda s: not s.node_states)
    update = order_update(first, waypoints=[waypoint(2, 0)])
    h.send_order(update)
    assert h.state.order_update_id == 1 and not h.state.errors
    final = h.run_until(lambda s: not s.node_states and not s.driving)
    assert (final.last_node_sequence_id, final.agv_position.x) == (4, 2.0)


def test_stitching_node_actions_are_not_run_again() -> None:
    h = RobotHarness()
    first = route((1, 0))
    first.nodes[1].actions.append(action("pick", "pick-1"))
    h.send_order(first)
    h.run_until(lambda s: all(a.action_status == "FINISHED" for a in s.action_states) and not s.node_states)
    update = order_update(first, waypoints=[waypoint(2, 0)])
    h.send_order(update)
    assert not h.state.errors
    h.run_until(lambda s: not s.node_states and not s.driving)
    assert [a.action_id for a in h.state.action_states] == ["pick-1"]


def test_accepting_a_new_order_clears_errors_and_old_states() -> None:
    h = RobotHarness()
    h.send_order(b"[]")
    assert h.state.errors
    order = route((0, 0))
    order.nodes[1].actions.append(action("pick", "p"))
    h.send_order(order)
    h.run_until(lambda s: not s.node_states and s.action_states[0].action_status == "FINISHED")
    assert h.state.errors == []
    h.send_order(route((0, 0), mission="m2"))
    assert h.state.order_id == "m2-n0-r0" and h.state.action_states == [] and h.state.errors == []


def test_a_resent_rejected_order_does_not_grow_the_error_list() -> None:
    h = RobotHarness()
    h.send_order(route((5, 0)))
    for _ in range(3):
        h.send_order(route((1, 0), start=(1, 0), mission="late"))
    (error,) = h.state.errors
    assert references(error)["headerId"] == "3"  # the latest resend


def test_node_position_is_reported_in_node_states() -> None:
    h = RobotHarness()
    h.send_order(route((1, 2)))
    assert h.state.node_states[0].node_position == NodePosition(
        x=1, y=2, theta=0.0, map_id="map", allowed_deviation_xy=0.0, allowed_deviation_theta=0.0
    )


def waypoint(x: float, y: float) -> Waypoint:
    return Waypoint(x, y, 0.0, "map")
