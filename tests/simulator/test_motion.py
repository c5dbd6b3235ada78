"""Driving: L-shaped steps, node traversal, deviations, horizon stop, instant mode, state events."""

from __future__ import annotations

import math

import orjson
import pytest

from simulator.motion import Target, VehiclePose, step_towards
from tests.simulator.conftest import RobotHarness, route
from vda5050.models import Edge
from vda5050.topics import Topic


def test_motion_goes_along_x_then_y_then_turns() -> None:
    target = Target.of(1.0, 0.5, math.pi / 2, None, None)
    poses = [VehiclePose(0.0, 0.0, 0.0)]
    while not target.reached_by(poses[-1]):
        poses.append(step_towards(poses[-1], target, 0.25))
    xs = [(p.x, p.y, p.theta) for p in poses]
    assert xs[:5] == [(0.0, 0.0, 0.0), (0.25, 0.0, 0.0), (0.5, 0.0, 0.0), (0.75, 0.0, 0.0), (1.0, 0.0, 0.0)]
    assert xs[5:7] == [(1.0, 0.25, 0.0), (1.0, 0.5, 0.0)]
    assert all(p.x == 1.0 and p.y == 0.5 for p in poses[7:])
    assert poses[-1].theta == pytest.approx(math.pi / 2)


def test_turning_takes_the_short_way_round() -> None:
    target = Target.of(0.0, 0.0, -3.0, None, None)
    assert step_towards(VehiclePose(0.0, 0.0, 3.0), target, 0.1).theta == pytest.approx(3.1)


def test_zero_or_negative_deviation_means_the_default_tolerance() -> None:
    for deviation in (None, 0.0, -1.0):
        target = Target.of(1.0, 0.0, None, deviation, deviation)
        assert target.reached_by(VehiclePose(1.04, 0.0, 0.0))
        assert not target.reached_by(VehiclePose(1.06, 0.0, 0.0))


def test_route_is_driven_node_by_node_and_progress_is_published() -> None:
    h = RobotHarness(speed=1.0, tick_period=0.25)
    accepted = h.states(h.send_order(route((1, 0), (1, 1))))
    assert len(accepted) == 1
    state = accepted[0]
    assert (state.order_id, state.last_node_id, state.last_node_sequence_id) == ("m1-n0-r0", "m1-n0-r0-s0", 0)
    assert [n.sequence_id for n in state.node_states] == [2, 4]
    assert [e.sequence_id for e in state.edge_states] == [1, 3]

    first_step = h.tick()
    assert h.state.agv_position.x == 0.25 and h.state.driving
    assert h.state.velocity.vx == pytest.approx(1.0)
    assert any(m.kind == Topic.STATE for m in first_step)  # starting to drive is an event

    h.run_until(lambda s: s.last_node_sequence_id == 2)
    assert [n.sequence_id for n in h.state.node_states] == [4]
    assert [e.sequence_id for e in h.state.edge_states] == [3]
    assert h.states()[-1].last_node_sequence_id == 2  # traversal was published at once

    final = h.run_until(lambda s: not s.driving)
    assert (final.last_node_id, final.node_states, final.edge_states) == ("m1-n0-r0-s4", [], [])
    assert (final.agv_position.x, final.agv_position.y) == (1.0, 1.0)
    assert h.states()[-1].driving is False


def test_node_counts_as_reached_within_its_allowed_deviation() -> None:
    h = RobotHarness(speed=1.0, tick_period=0.25)
    h.send_order(route((2, 0), deviation_xy=0.6))
    final = h.run_until(lambda s: not s.node_states)
    assert final.agv_position.x == 1.5  # 0.5 m short of the node, within 0.6 m
    h.tick()
    assert h.state.agv_position.x == 1.5 and not h.state.driving


def test_edge_max_speed_slows_the_robot() -> None:
    h = RobotHarness(speed=1.0, tick_period=0.25)
    order = route((2, 0))
    order.edges[0] = Edge.model_validate({**order.edges[0].model_dump(), "max_speed": 0.4})
    h.send_order(order)
    h.tick()
    assert h.state.agv_position.x == pytest.approx(0.1)


def test_robot_stops_at_the_decision_point_and_asks_for_more() -> None:
    h = RobotHarness(speed=1.0, tick_period=0.25)
    h.send_order(route((1, 0), horizon=((2, 0),)))
    h.run_until(lambda s: s.last_node_sequence_id == 2)
    h.run(2.0)
    state = h.state
    assert state.agv_position.x == 1.0 and not state.driving
    assert [(n.sequence_id, n.released) for n in state.node_states] == [(4, False)]
    assert [(e.sequence_id, e.released) for e in state.edge_states] == [(3, False)]
    assert state.new_base_request is True


def test_instant_mode_completes_the_order_in_the_answering_state() -> None:
    h = RobotHarness(instant=True)
    state = h.states(h.send_order(route((3, 0), (3, 4))))[-1]
    assert (state.last_node_sequence_id, state.node_states, state.edge_states) == (4, [], [])
    assert (state.agv_position.x, state.agv_position.y) == (3.0, 4.0)
    assert state.driving is False


def test_speed_zero_means_instant() -> None:
    h = RobotHarness(speed=0.0)
    state = h.states(h.send_order(route((5, 5))))[-1]
    assert state.last_node_sequence_id == 2 and not state.node_states


def test_state_and_visualization_are_published_periodically_with_header_ids_per_topic() -> None:
    h = RobotHarness(state_period=1.0, visualization_period=0.5, tick_period=0.25)
    h.run(3.0)
    by_kind: dict[str, list[int]] = {}
    for message in h.sent:
        by_kind.setdefault(message.kind, []).append(orjson.loads(message.payload)["headerId"])
    assert by_kind[Topic.STATE] == list(range(len(by_kind[Topic.STATE])))
    assert by_kind[Topic.VISUALIZATION] == list(range(len(by_kind[Topic.VISUALIZATION])))
    assert len(by_kind[Topic.STATE]) == 4  # at connect, then once a second for 3 s
    assert len(by_kind[Topic.VISUALIZATION]) == 7
