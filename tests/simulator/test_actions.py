"""Node actions, instant actions and the failure period."""

from __future__ import annotations

import math

import orjson
import pytest

from tests.simulator.conftest import RobotHarness, action, keep_busy, route
from vda5050.models import ActionStatus, Error, OrderContent
from vda5050.topics import Topic

FINISHED, FAILED, RUNNING, WAITING = (
    ActionStatus.FINISHED,
    ActionStatus.FAILED,
    ActionStatus.RUNNING,
    ActionStatus.WAITING,
)


def order_with(*actions, at: tuple[float, float] = (0.0, 0.0), mission: str = "m1") -> OrderContent:
    """A one-node order (Dispatch's action leaf) carrying ``actions``."""
    order = route(start=at, mission=mission)
    order.nodes[0].actions.extend(actions)
    return order


def errors_by_type(h: RobotHarness) -> dict[str, Error]:
    return {error.error_type: error for error in h.state.errors}


def refs(error: Error) -> dict[str, str]:
    return {r.reference_key: r.reference_value for r in error.error_references or ()}


def test_dummy_action_runs_for_its_time_then_finishes() -> None:
    h = RobotHarness(tick_period=0.25)
    h.send_order(order_with(action("dummy_action", "a1", should_fail="0", time="1.0")))
    assert h.action_state("a1").action_status == RUNNING
    h.tick(3)
    assert h.action_state("a1").action_status == RUNNING
    finished = h.states(h.tick())
    assert finished[-1].action_states[0].action_status == FINISHED  # the change was published
    assert h.state.errors == []


@pytest.mark.parametrize("should_fail", [True, 1, "1", "true", "True"])
def test_dummy_action_that_should_fail_fails_with_a_fatal_error(should_fail) -> None:
    h = RobotHarness()
    h.send_order(order_with(action("dummy_action", "a1", should_fail=should_fail, time=0.5)))
    h.run(0.5)
    assert h.action_state("a1").action_status == FAILED
    (error,) = h.state.errors
    assert (error.error_level, error.error_description) == ("FATAL", "Action failure")
    assert refs(error)["actionId"] == "a1"


@pytest.mark.parametrize(
    "parameters",
    [{}, {"time": 1}, {"should_fail": False}, {"should_fail": "maybe", "time": 1}, {"time": "x"}],
)
def test_dummy_action_with_missing_or_bad_parameters_fails_at_once(parameters: dict) -> None:
    h = RobotHarness()
    h.send_order(order_with(action("dummy_action", "a1", **parameters)))
    assert h.action_state("a1").action_status == FAILED
    assert h.state.errors[0].error_level == "FATAL"


def test_unknown_action_type_fails_like_a_real_robot() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("teleport", "a1")))
    state = h.action_state("a1")
    assert state.action_status == FAILED and "teleport" in state.result_description
    assert refs(h.state.errors[0]) == {"actionId": "a1", "orderId": "m1-n0-r0"}


def test_a_failed_action_abandons_the_rest_of_the_order() -> None:
    h = RobotHarness()
    order = route((2, 0))
    order.nodes[0].actions.append(action("dummy_action", "boom", should_fail=True, time=0))
    order.nodes[1].actions.append(action("pick", "later"))
    h.send_order(order)
    assert h.state.node_states == [] and h.state.edge_states == []
    assert [a.action_status for a in h.state.action_states] == [FAILED, FAILED]
    h.run(1.0)
    assert h.state.agv_position.x == 0.0
    h.send_order(route((1, 0), mission="m2"))  # idle again, the next order is taken
    assert h.state.order_id == "m2-n0-r0" and h.state.errors == []


def test_actions_run_one_at_a_time_while_the_robot_stands_still() -> None:
    h = RobotHarness(tick_period=0.25)
    order = route((1, 0), (2, 0))
    order.nodes[1].actions += [
        action("dummy_action", "first", should_fail=False, time=1),
        action("dummy_action", "second", should_fail=False, time=1),
    ]
    h.send_order(order)
    h.run_until(lambda s: s.last_node_sequence_id == 2)
    assert [a.action_status for a in h.state.action_states] == [RUNNING, WAITING]
    h.run(1.0)
    assert [a.action_status for a in h.state.action_states] == [FINISHED, RUNNING]
    assert h.state.agv_position.x == 1.0 and not h.state.driving
    h.run(1.0)
    h.tick()
    assert h.state.action_states[1].action_status == FINISHED
    assert h.state.agv_position.x > 1.0


def test_edge_actions_run_before_the_robot_drives_the_edge() -> None:
    h = RobotHarness()
    order = route((1, 0))
    order.edges[0].actions.append(action("dummy_action", "on-edge", should_fail=False, time=0.5))
    h.send_order(order)
    assert h.action_state("on-edge").action_status == RUNNING
    h.tick()
    assert h.action_state("on-edge").action_status == RUNNING and h.state.agv_position.x == 0.0
    h.run_until(lambda s: not s.node_states)
    assert h.action_state("on-edge").action_status == FINISHED


def test_pause_order_runs_until_stop_teleop() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("pause_order", "p")))
    h.run(5.0)
    assert h.action_state("p").action_status == RUNNING
    h.send_actions(action("stopTeleop", "stop"))
    assert h.action_state("p").action_status == FINISHED
    assert h.action_state("stop").action_status == FINISHED


def test_load_map_switches_the_map_after_a_second() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("load_map", "lm", map_id="warehouse")))
    assert h.state.agv_position.map_id == "map"
    h.run(1.0)
    assert h.action_state("lm").action_status == FINISHED
    assert h.state.agv_position.map_id == "warehouse"


def test_load_map_without_map_id_fails() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("load_map", "lm")))
    assert h.action_state("lm").action_status == FAILED


def test_pick_and_drop_change_the_loads() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("pick", "pick", loadId="box-7", loadType="EPAL")))
    h.run(1.0)
    assert [(load.load_id, load.load_type) for load in h.state.loads] == [("box-7", "EPAL")]
    h.send_order(order_with(action("drop", "drop"), mission="m2"))
    h.run(1.0)
    assert h.state.loads == []


def test_cancel_order_stops_fails_waiting_actions_and_empties_the_graph() -> None:
    h = RobotHarness()
    order = route((3, 0), (3, 3))
    order.nodes[2].actions.append(action("pick", "never"))
    h.send_order(order)
    h.tick(2)
    state = h.states(h.send_actions(action("cancelOrder", "cancel")))[-1]
    assert (state.node_states, state.edge_states, state.driving) == ([], [], False)
    assert (state.order_id, state.last_node_id) == ("m1-n0-r0", "m1-n0-r0-s0")  # kept
    statuses = {a.action_id: a.action_status for a in state.action_states}
    assert statuses == {"never": FAILED, "cancel": FINISHED}
    h.run(1.0)
    assert h.state.agv_position.x == 0.5
    h.send_order(route((0, 0), start=(0.5, 0), mission="m2"))  # the next order starts where it stopped
    assert h.state.order_id == "m2-n0-r0"


def test_cancel_order_fails_a_running_action() -> None:
    h = RobotHarness()
    h.send_order(order_with(action("pause_order", "p")))
    h.send_actions(action("cancelOrder", "cancel"))
    assert (h.action_state("p").action_status, h.action_state("cancel").action_status) == (FAILED, FINISHED)


def test_cancel_order_without_an_order_is_a_warning_and_fails() -> None:
    h = RobotHarness()
    h.send_actions(action("cancelOrder", "c1"))
    assert h.action_state("c1").action_status == FAILED
    error = errors_by_type(h)["noOrderToCancel"]
    assert error.error_level == "WARNING" and refs(error)["actionId"] == "c1"
    h.send_order(route((1, 0)))
    h.run_until(lambda s: not s.node_states)
    h.send_actions(action("cancelOrder", "c2"))  # the order is done: nothing to cancel either
    assert h.action_state("c2").action_status == FAILED


def test_pause_stops_driving_until_stop_pause() -> None:
    h = RobotHarness()
    h.send_order(route((3, 0)))
    h.tick()
    paused = h.states(h.send_actions(action("startPause", "pause")))[-1]
    assert paused.paused is True and paused.driving is False
    h.run(2.0)
    assert h.state.agv_position.x == 0.25
    h.send_actions(action("stopPause", "resume"))
    h.tick()
    assert h.state.paused is False and h.state.agv_position.x == 0.5
    assert {a.action_status for a in h.state.action_states} == {FINISHED}


def test_teleop_stops_driving_until_stop_teleop() -> None:
    h = RobotHarness()
    h.send_order(route((3, 0)))
    h.send_actions(action("startTeleop", "t1"))
    h.run(1.0)
    assert h.state.agv_position.x == 0.0
    h.send_actions(action("stopTeleop", "t2"))
    h.tick()
    assert h.state.agv_position.x == 0.25
    assert [h.action_state(i).action_status for i in ("t1", "t2")] == [FINISHED, FINISHED]


def test_state_request_publishes_a_state() -> None:
    h = RobotHarness()
    h.run(0.5)
    states = h.states(h.send_actions(action("stateRequest", "sr")))
    assert len(states) == 1
    assert states[0].action_states[0].action_status == FINISHED


@pytest.mark.parametrize(
    ("robot_type", "agv_class", "speed_max"),
    [("CARRIER", "CARRIER", 2.0), ("FORKLIFT", "FORKLIFT", 2.0), ("MANIPULATOR", "MANIPULATOR", 0.0)],
)
def test_factsheet_request_publishes_a_complete_factsheet(
    robot_type: str, agv_class: str, speed_max: float
) -> None:
    h = RobotHarness(f"arm01,0,0,0,map,0,50,Acme,sn-1,{robot_type}", speed=2.0)
    (message,) = [m for m in h.send_actions(action("factsheetRequest", "fr")) if m.kind == Topic.FACTSHEET]
    factsheet = orjson.loads(message.payload)
    assert message.retain
    assert factsheet["typeSpecification"]["agvClass"] == agv_class
    assert factsheet["physicalParameters"]["speedMax"] == speed_max
    assert (factsheet["manufacturer"], factsheet["serialNumber"]) == ("Acme", "sn-1")
    actions = {a["actionType"] for a in factsheet["protocolFeatures"]["agvActions"]}
    assert {
        "dummy_action",
        "pause_order",
        "load_map",
        "pick",
        "drop",
        "cancelOrder",
        "factsheetRequest",
    } <= actions
    assert h.action_state("fr").action_status == FINISHED


def test_init_position_sets_the_pose_when_idle() -> None:
    h = RobotHarness()
    h.send_actions(
        action("initPosition", "ip", x=4.0, y=-2.0, theta=math.pi / 2, mapId="floor2", lastNodeId="n9")
    )
    state = h.state
    assert (state.agv_position.x, state.agv_position.y, state.agv_position.map_id) == (4.0, -2.0, "floor2")
    assert state.last_node_id == "n9"
    h.send_actions(action("initPosition", "bad", x=1))
    assert h.action_state("bad").action_status == FAILED


def test_unknown_instant_action_fails_with_a_warning() -> None:
    h = RobotHarness()
    h.send_actions(action("selfDestruct", "x"))
    assert h.action_state("x").action_status == FAILED
    assert h.state.errors[0].error_level == "WARNING"


def test_a_resent_instant_action_is_not_run_twice() -> None:
    h = RobotHarness()
    h.send_order(route((3, 0)))
    h.send_actions(action("cancelOrder", "c"))
    h.send_actions(action("cancelOrder", "c"))
    assert h.action_state("c").action_status == FINISHED
    assert "noOrderToCancel" not in errors_by_type(h)


def test_malformed_instant_actions_are_a_validation_error() -> None:
    h = RobotHarness()
    h.record(h.robot.receive(Topic.INSTANT_ACTIONS, b'{"headerId": 4, "actions": [{}]}', h.now))
    error = h.state.errors[0]
    assert error.error_type == "validationError"
    assert refs(error) == {"topic": "instantActions", "headerId": "4"}


def test_failure_period_fails_every_nth_order_with_a_fatal_error() -> None:
    h = RobotHarness("carter01,0,0,0,map,2")
    outcomes = []
    for index in range(4):
        order = route((index + 1.0, 0), start=(float(index), 0), mission=f"m{index}")
        h.send_order(order)
        h.run_until(lambda s: not s.node_states and not s.driving)
        errors = h.state.errors
        outcomes.append(
            (h.state.last_node_sequence_id, [(e.error_level, e.error_description) for e in errors])
        )
        if errors:
            assert refs(errors[0])["nodeId"] == order.nodes[0].node_id
            h.send_actions(
                action("initPosition", f"back{index}", x=index + 1.0, y=0.0, theta=0.0, mapId="map")
            )
    assert outcomes == [
        (2, []),
        (0, [("FATAL", "Failure period reached")]),
        (2, []),
        (0, [("FATAL", "Failure period reached")]),
    ]


def test_failure_period_as_warning_lets_the_order_complete() -> None:
    h = RobotHarness("carter01,0,0,0,map,1", fail_as_warning=True)
    h.send_order(route((1, 0)))
    final = h.run_until(lambda s: not s.node_states and not s.driving)
    assert final.last_node_sequence_id == 2
    assert [(e.error_level, e.error_description) for e in final.errors] == [
        ("WARNING", "Failure period reached")
    ]


@pytest.mark.parametrize("version", ["2.0.0", "2.1.0"])
def test_every_message_of_a_busy_robot_is_valid_for_its_version(version: str) -> None:
    h = RobotHarness(version=version, visualization_period=0.5)
    keep_busy(h)
    assert {m.kind for m in h.sent} == {Topic.CONNECTION, Topic.FACTSHEET, Topic.STATE, Topic.VISUALIZATION}
    assert {orjson.loads(m.payload)["version"] for m in h.sent} == {version}
    maps = h.state.maps
    assert (maps is None) == (version == "2.0.0")  # the maps array exists since 2.1.0
