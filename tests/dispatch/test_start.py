"""Starting a queued mission: what holds it back, what ends it before it starts, and the first order."""

from datetime import timedelta
from typing import Any

import pytest

from dispatch.ending import DEADLINE_PASSED
from dispatch.stations import CHARGING
from dispatch.vocabulary import FailureCategory, Lifecycle, MissionPurpose, MissionState, RobotState
from tests.dispatch.builders import (
    IDLE_STATE,
    MISSION,
    NOW,
    POSE,
    action,
    checked_step,
    error,
    instant_action,
    mission,
    move,
    orders_sent,
    robot_state,
    robot_view,
    route,
)
from vda5050.models import ActionStatus, ActionType, ErrorLevel, OperatingMode


@pytest.mark.parametrize(
    ("robot", "state", "actions", "waiting_reason"),
    [
        pytest.param({"online": False}, IDLE_STATE, [], "Robot is offline", id="offline"),
        pytest.param({}, None, [], "Robot is offline", id="no-state-yet"),
        pytest.param({"state": RobotState.TELEOP}, IDLE_STATE, [], "Robot is in teleop", id="teleop"),
        pytest.param({"state": RobotState.CHARGING}, robot_state(charging=True), [], CHARGING, id="charging"),
        pytest.param(
            {"lifecycle": Lifecycle.PENDING_DELETE},
            IDLE_STATE,
            [],
            "Robot is being deleted",
            id="robot-deleted",
        ),
        pytest.param(
            {"battery_critical_level": 20.0},
            robot_state(battery=12.5),
            [],
            "Battery 12.5% is below the robot's critical level 20%",
            id="battery-critical",
        ),
        pytest.param(
            {}, robot_state(operating_mode=OperatingMode.MANUAL), [], "Robot is in MANUAL mode", id="manual"
        ),
        pytest.param(
            {},
            robot_state(operating_mode=OperatingMode.SERVICE),
            [],
            "Robot is in SERVICE mode",
            id="service",
        ),
        pytest.param(
            {},
            robot_state(order_id="old-n0-r0", node_states=[2, 4]),
            [],
            "Robot is busy with an earlier order",
            id="busy-with-nodes",
        ),
        pytest.param(
            {},
            robot_state(order_id="old", action_states=[("a1", ActionStatus.RUNNING)]),
            [],
            "Robot is busy with an earlier order",
            id="busy-with-action",
        ),
        pytest.param(
            {},
            IDLE_STATE,
            [instant_action(ActionType.CANCEL_ORDER, sent_at=NOW)],
            "Waiting for the robot to cancel its previous order",
            id="cancel-order-pending",
        ),
    ],
)
def test_a_queued_mission_waits_and_says_why(
    robot: dict[str, Any], state, actions, waiting_reason: str
) -> None:
    queued = mission()

    result = checked_step(state=state, mission=queued, robot=robot_view(**robot), actions=actions)

    assert result.mission.state == MissionState.PENDING
    assert result.mission.waiting_reason == waiting_reason
    assert result.mission.start_timestamp is None
    assert orders_sent(result) == []
    assert result.robot_state == robot_view(**robot).state


@pytest.mark.parametrize(
    "state",
    [
        pytest.param(robot_state(battery=10.0), id="battery-at-critical-level"),
        pytest.param(robot_state(operating_mode=OperatingMode.SEMIAUTOMATIC), id="semiautomatic"),
        pytest.param(robot_state(errors=[error("obstacle", ErrorLevel.WARNING)]), id="warning"),
        pytest.param(
            robot_state(order_id="old", action_states=[("a1", ActionStatus.FAILED)]), id="old-action-final"
        ),
    ],
)
def test_a_queued_mission_starts_whenever_the_robot_can_take_it(state) -> None:
    result = checked_step(state=state, mission=mission())

    assert result.mission.state == MissionState.RUNNING
    assert len(orders_sent(result)) == 1


def test_a_charging_trip_starts_below_the_critical_level_where_other_missions_wait() -> None:
    low = robot_state(battery=5.0)

    trip = checked_step(state=low, mission=mission(purpose=MissionPurpose.CHARGE))
    parking = checked_step(state=low, mission=mission(purpose=MissionPurpose.PARK))

    assert trip.mission.state == MissionState.RUNNING and len(orders_sent(trip)) == 1
    assert parking.mission.state == MissionState.PENDING
    assert parking.mission.waiting_reason.startswith("Battery 5% is below")


def test_a_robot_due_to_charge_runs_its_charging_trip_and_nothing_else_until_charged() -> None:
    due = robot_view(charge_threshold=30.0)  # it can charge at a charger it may use, at or below 30 %
    low, charged = robot_state(battery=25.0), robot_state(battery=31.0)

    waiting = checked_step(robot=due, state=low, mission=mission())
    trip = checked_step(robot=due, state=low, mission=mission(purpose=MissionPurpose.CHARGE))
    later = checked_step(robot=due, state=charged, mission=mission())
    never_due = checked_step(robot=robot_view(), state=low, mission=mission())

    assert waiting.mission.state == MissionState.PENDING and orders_sent(waiting) == []
    assert (
        waiting.mission.waiting_reason == "Battery 25% is due to charge (at or below 30%): it charges first"
    )
    assert trip.mission.state == MissionState.RUNNING
    assert later.mission.state == never_due.mission.state == MissionState.RUNNING


def test_a_mission_bound_to_a_robot_due_to_charge_goes_back_to_the_pool() -> None:
    bound = mission(assignment=[{"robot": "r1", "bound_at": "t", "released_at": None, "reason": None}])

    result = checked_step(
        robot=robot_view(charge_threshold=30.0), state=robot_state(battery=25.0), mission=bound
    )

    assert result.release is not None and "due to charge" in result.release


def test_a_waiting_reason_is_cleared_when_the_mission_starts() -> None:
    waiting = checked_step(state=robot_state(battery=5.0), mission=mission()).mission

    started = checked_step(state=IDLE_STATE, mission=waiting)

    assert (started.mission.state, started.mission.waiting_reason) == (MissionState.RUNNING, None)


def test_start_sets_running_start_time_robot_on_task_and_sends_the_first_route_order() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(route("r", (5.0, 6.0), (7.0, 8.0))))

    started = result.mission
    assert (started.state, started.start_timestamp, started.end_timestamp) == (
        MissionState.RUNNING,
        NOW,
        None,
    )
    assert started.node_status == {
        "root": {"state": MissionState.RUNNING, "error_msg": None},
        "r": {"state": MissionState.RUNNING, "error_msg": None},
    }
    assert (started.current_node, started.attempts, started.order_sent_at) == (0, {"r": 1}, NOW)
    assert started.order_accepted is False
    assert result.robot_state == RobotState.ON_TASK
    [order] = orders_sent(result)
    assert started.order == order.model_dump(mode="json", by_alias=True, exclude_none=True)
    assert (order.order_id, order.order_update_id) == (f"{MISSION}-n0-r0", 0)
    assert [(n.node_id, n.sequence_id) for n in order.nodes] == [
        ("m1-n0-r0-s0", 0),
        ("m1-n0-r0-s2", 2),
        ("m1-n0-r0-s4", 4),
    ]
    assert [(e.edge_id, e.start_node_id, e.end_node_id) for e in order.edges] == [
        ("m1-n0-r0-e1", "m1-n0-r0-s0", "m1-n0-r0-s2"),
        ("m1-n0-r0-e3", "m1-n0-r0-s2", "m1-n0-r0-s4"),
    ]
    start = order.nodes[0].node_position
    assert (start.x, start.y, start.map_id, start.allowed_deviation_xy) == (POSE[0], POSE[1], POSE[3], 0.5)
    assert [(n.node_position.x, n.node_position.y) for n in order.nodes[1:]] == [(5.0, 6.0), (7.0, 8.0)]
    assert all(n.released for n in order.nodes) and all(e.released for e in order.edges)


def test_the_first_order_of_a_move_starts_at_the_robot_and_drives_along_its_heading() -> None:
    result = checked_step(
        state=robot_state(pose=(1.0, 2.0, 0.0, "map")), mission=mission(move("mv", distance=3.0))
    )

    [order] = orders_sent(result)
    assert order.order_id == "m1-n0-r0"
    assert [(n.node_position.x, n.node_position.y) for n in order.nodes] == [(1.0, 2.0), (4.0, 2.0)]


def test_the_first_order_of_an_action_is_one_node_with_the_action_and_its_parameters() -> None:
    result = checked_step(
        state=IDLE_STATE, mission=mission(action("a", "dummy_action", time=2, should_fail=False))
    )

    [order] = orders_sent(result)
    [node] = order.nodes
    assert (order.order_id, node.node_id, order.edges) == ("m1-n0-r0", "m1-n0-r0-s0", [])
    [sent] = node.actions
    assert (sent.action_type, sent.action_id) == ("dummy_action", "m1-n0-r0-a0")
    assert [(p.key, p.value) for p in sent.action_parameters] == [("should_fail", False), ("time", 2)]


def test_a_robot_without_a_position_fails_the_leaf_instead_of_guessing_a_start() -> None:
    result = checked_step(state=robot_state(pose=None), mission=mission())

    assert result.mission.state == MissionState.FAILED
    assert result.mission.node_status["r"] == {
        "state": MissionState.FAILED,
        "error_msg": "Robot does not report its position",
    }
    assert orders_sent(result) == []


def test_a_queued_mission_past_its_deadline_fails_without_starting() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(deadline=NOW - timedelta(seconds=1)))

    ended = result.mission
    assert (ended.state, ended.failure_category) == (MissionState.FAILED, FailureCategory.DEADLINE)
    assert (ended.failure_reason, ended.start_timestamp, ended.end_timestamp) == (
        DEADLINE_PASSED,
        None,
        NOW,
    )
    assert ended.node_status["root"]["state"] == MissionState.FAILED
    assert ended.node_status["r"]["state"] == MissionState.PENDING
    assert (result.messages, result.robot_state, result.delete_mission) == ([], RobotState.IDLE, False)


def test_a_queued_mission_before_its_deadline_starts() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(deadline=NOW + timedelta(seconds=1)))

    assert result.mission.state == MissionState.RUNNING


def test_a_queued_mission_past_its_deadline_fails_even_while_the_robot_is_offline() -> None:
    result = checked_step(state=None, mission=mission(deadline=NOW), robot=robot_view(online=False))

    assert (result.mission.state, result.mission.failure_category) == (
        MissionState.FAILED,
        FailureCategory.DEADLINE,
    )


def test_a_queued_mission_marked_for_deletion_is_deleted_without_starting() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(lifecycle=Lifecycle.PENDING_DELETE))

    assert result.delete_mission is True
    assert (result.mission.state, result.messages, result.robot_state) == (
        MissionState.PENDING,
        [],
        RobotState.IDLE,
    )


def test_a_queued_mission_with_needs_canceled_ends_canceled_without_starting() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(needs_canceled=True))

    assert (result.mission.state, result.mission.failure_category) == (
        MissionState.CANCELED,
        FailureCategory.CANCELED,
    )
    assert (result.messages, result.robot_state) == ([], RobotState.IDLE)


def test_a_queued_mission_waits_while_the_robot_reports_a_fatal_error() -> None:
    result = checked_step(
        state=robot_state(errors=[error("laserScannerFault", ErrorLevel.FATAL, "scanner down")]),
        mission=mission(),
    )

    assert result.mission.state == MissionState.PENDING
    assert result.mission.waiting_reason is not None
    assert orders_sent(result) == []


def test_a_mission_of_only_a_constant_completes_in_its_first_step() -> None:
    result = checked_step(
        state=IDLE_STATE, mission=mission({"name": "c", "parent": "root", "constant": {"success": True}})
    )

    assert (result.mission.state, result.mission.start_timestamp, result.mission.end_timestamp) == (
        MissionState.COMPLETED,
        NOW,
        NOW,
    )
    assert (result.messages, result.robot_state) == ([], RobotState.IDLE)


def test_a_mission_whose_route_update_names_a_missing_node_fails_with_the_reason() -> None:
    result = checked_step(state=IDLE_STATE, mission=mission(update_nodes={"missing": {"waypoints": []}}))

    assert (result.mission.state, result.mission.failure_reason, result.mission.failure_category) == (
        MissionState.FAILED,
        "Node missing does not exist",
        FailureCategory.ROBOT_APP,
    )
    assert (result.messages, result.robot_state) == ([], RobotState.IDLE)
