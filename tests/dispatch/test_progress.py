"""A running leaf's progress: routes, actions, pause_order, robot errors, and how the mission ends."""

from dataclasses import replace

import pytest

from dispatch.step import ACTION_FAILURE, PAUSE_ORDER
from dispatch.vocabulary import FailureCategory, MissionState, RobotState
from tests.dispatch.builders import (
    NOW,
    action,
    cancel_actions,
    error,
    finished,
    instant_actions_sent,
    move,
    on_order,
    orders_sent,
    route,
    selector,
    sequence,
    started,
)
from vda5050.models import ActionStatus, ActionType, ErrorLevel

THREE_EXACT_WAYPOINTS = route("r", (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), allowedDeviationXY=0.0)


@pytest.mark.parametrize(("reached", "task_status"), [(0, 0), (2, 1), (4, 2)])
def test_task_status_counts_the_exactly_reached_waypoints(reached: int, task_status: int) -> None:
    dispatcher = started(THREE_EXACT_WAYPOINTS)

    dispatcher.step(on_order(dispatcher.order, reached, driving=True), after=1.0)

    assert dispatcher.mission.task_status == {"r": task_status}
    assert dispatcher.node("r") == MissionState.RUNNING


def test_task_status_ignores_waypoints_with_a_tolerance() -> None:
    dispatcher = started(route("r", (1.0, 0.0), (2.0, 0.0), allowedDeviationXY=0.3))

    dispatcher.step(on_order(dispatcher.order, 2), after=1.0)

    assert dispatcher.mission.task_status == {"r": 0}


def test_a_route_is_not_complete_while_the_robot_still_has_nodes_to_go() -> None:
    dispatcher = started(THREE_EXACT_WAYPOINTS)

    dispatcher.step(on_order(dispatcher.order, 4), after=1.0)

    assert dispatcher.node("r") == MissionState.RUNNING


def test_a_route_is_not_complete_at_its_last_node_while_an_action_still_runs() -> None:
    dispatcher = started(THREE_EXACT_WAYPOINTS)

    dispatcher.step(on_order(dispatcher.order, 6, extra_actions=[("x", ActionStatus.RUNNING)]), after=1.0)

    assert (dispatcher.node("r"), dispatcher.mission.task_status) == (MissionState.RUNNING, {"r": 3})


def test_a_route_completes_at_its_last_node_with_the_robot_idle_and_the_mission_with_it() -> None:
    dispatcher = started(THREE_EXACT_WAYPOINTS)
    dispatcher.mission.failure_reason = "left over from a recovered branch"

    result = dispatcher.step(finished(dispatcher.order), after=1.0)

    ended = dispatcher.mission
    assert (ended.state, ended.end_timestamp, ended.failure_reason, ended.failure_category) == (
        MissionState.COMPLETED,
        NOW.replace(second=1),
        None,
        None,
    )
    assert (ended.task_status, ended.order, ended.current_node) == ({"r": 3}, None, 0)
    assert ended.node_status == {
        "root": {"state": MissionState.COMPLETED, "error_msg": None},
        "r": {"state": MissionState.COMPLETED, "error_msg": None},
    }
    assert (result.robot_state, result.messages) == (RobotState.IDLE, [])


def test_a_move_completes_at_its_target_node() -> None:
    dispatcher = started(move("mv"))

    dispatcher.step(finished(dispatcher.order), after=1.0)

    assert dispatcher.mission.state == MissionState.COMPLETED


def test_a_completed_leaf_sends_the_next_leafs_order_and_moves_current_node() -> None:
    dispatcher = started(move("r1"), route("r2", (8.0, 9.0)))  # a route after a route goes ahead

    result = dispatcher.step(finished(dispatcher.order), after=1.0)

    [order] = orders_sent(result)
    assert order.order_id == "m1-n1-r0"
    assert (order.nodes[-1].node_position.x, order.nodes[-1].node_position.y) == (8.0, 9.0)
    assert (dispatcher.node("r1"), dispatcher.node("r2"), dispatcher.mission.current_node) == (
        MissionState.COMPLETED,
        MissionState.RUNNING,
        1,
    )
    assert (dispatcher.mission.order_accepted, dispatcher.mission.order_sent_at) == (False, dispatcher.now)
    assert result.robot_state == RobotState.ON_TASK


def test_a_finished_action_completes_its_leaf() -> None:
    dispatcher = started(action("a"))

    dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FINISHED), after=1.0)

    assert (dispatcher.node("a"), dispatcher.mission.state) == (
        MissionState.COMPLETED,
        MissionState.COMPLETED,
    )


@pytest.mark.parametrize("status", [ActionStatus.WAITING, ActionStatus.INITIALIZING, ActionStatus.RUNNING])
def test_an_action_still_in_progress_keeps_its_leaf_running(status: ActionStatus) -> None:
    dispatcher = started(action("a"))

    result = dispatcher.step(on_order(dispatcher.order, 0, action_status=status), after=1.0)

    assert dispatcher.node("a") == MissionState.RUNNING
    assert result.robot_state == RobotState.ON_TASK


def test_a_failed_action_fails_its_leaf_with_the_robots_error_text() -> None:
    dispatcher = started(action("a"))
    order = dispatcher.order
    action_id = order.nodes[0].actions[0].action_id

    dispatcher.step(
        on_order(
            order,
            0,
            action_status=ActionStatus.FAILED,
            errors=[error("actionError", ErrorLevel.WARNING, "gripper jammed", actionId=action_id)],
        ),
        after=1.0,
    )

    assert dispatcher.mission.node_status["a"] == {
        "state": MissionState.FAILED,
        "error_msg": "gripper jammed",
    }
    assert (dispatcher.mission.state, dispatcher.mission.failure_reason) == (
        MissionState.FAILED,
        "gripper jammed",
    )
    assert dispatcher.mission.failure_category == FailureCategory.ROBOT_APP


def test_a_failed_action_without_an_error_fails_its_leaf_with_action_failure() -> None:
    dispatcher = started(action("a"))

    dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FAILED), after=1.0)

    assert dispatcher.mission.node_status["a"] == {
        "state": MissionState.FAILED,
        "error_msg": ACTION_FAILURE,
    }
    assert dispatcher.mission.failure_reason == ACTION_FAILURE


def test_pause_order_hands_the_robot_to_teleop_while_it_runs_and_back_when_finished() -> None:
    dispatcher = started(action("p", PAUSE_ORDER), route("r"))

    running = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.RUNNING), after=1.0)
    assert (running.robot_state, dispatcher.node("p")) == (RobotState.TELEOP, MissionState.RUNNING)

    done = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FINISHED), after=1.0)
    assert (done.robot_state, dispatcher.node("p"), dispatcher.node("r")) == (
        RobotState.ON_TASK,
        MissionState.COMPLETED,
        MissionState.RUNNING,
    )
    assert [order.order_id for order in orders_sent(done)] == ["m1-n1-r0"]


def test_pause_order_not_yet_reported_leaves_the_robot_on_task() -> None:
    dispatcher = started(action("p", PAUSE_ORDER))

    result = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    assert result.robot_state == RobotState.ON_TASK


def test_a_running_action_of_another_type_does_not_switch_to_teleop() -> None:
    dispatcher = started(action("a", "dock_robot"))

    result = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.RUNNING), after=1.0)

    assert result.robot_state == RobotState.ON_TASK


def _order_reference(order, kind: str) -> dict[str, str]:
    return {
        "order": {"orderId": order.order_id},
        "node": {"nodeId": order.nodes[-1].node_id},
        "edge": {"edgeId": order.edges[0].edge_id} if order.edges else {},
        "action": {"actionId": order.nodes[0].actions[0].action_id} if order.nodes[0].actions else {},
    }[kind]


@pytest.mark.parametrize(
    ("tree", "kind"),
    [
        pytest.param(route("r", (1.0, 0.0), (2.0, 0.0)), "order", id="route-orderId"),
        pytest.param(route("r", (1.0, 0.0), (2.0, 0.0)), "node", id="route-nodeId"),
        pytest.param(route("r", (1.0, 0.0), (2.0, 0.0)), "edge", id="route-edgeId"),
        pytest.param(action("r"), "action", id="action-actionId"),
    ],
)
def test_a_fatal_error_referencing_the_order_fails_the_leaf_and_cancels_the_busy_robots_order(
    tree, kind: str
) -> None:
    dispatcher = started(tree)
    order = dispatcher.order
    fatal = error("blocked", ErrorLevel.FATAL, "path blocked", **_order_reference(order, kind))

    result = dispatcher.step(
        on_order(order, 0, action_status=ActionStatus.RUNNING, errors=[fatal]), after=1.0
    )

    assert dispatcher.mission.node_status["r"] == {"state": MissionState.FAILED, "error_msg": "path blocked"}
    assert (dispatcher.mission.state, dispatcher.mission.failure_reason) == (
        MissionState.FAILED,
        "path blocked",
    )
    assert dispatcher.mission.failure_category == FailureCategory.ROBOT_APP
    [cancel] = cancel_actions(result.actions)
    assert cancel.action_id.startswith(f"{order.order_id}-cancel")
    assert [(a.action_type, a.action_id) for a in instant_actions_sent(result)] == [
        (ActionType.CANCEL_ORDER, cancel.action_id)
    ]
    assert result.robot_state == RobotState.IDLE


def test_a_fatal_error_with_the_robot_already_idle_sends_no_cancel() -> None:
    dispatcher = started(route("r", (1.0, 0.0), (2.0, 0.0)))
    order = dispatcher.order
    fatal = error("blocked", ErrorLevel.FATAL, "path blocked", orderId=order.order_id)

    result = dispatcher.step(
        on_order(order, 2, errors=[fatal]).model_copy(update={"node_states": [], "edge_states": []}),
        after=1.0,
    )

    assert dispatcher.mission.state == MissionState.FAILED
    assert (result.actions, result.messages) == ([], [])


def test_a_fatal_error_without_references_fails_the_leaf() -> None:
    dispatcher = started()

    dispatcher.step(
        on_order(dispatcher.order, 0, errors=[error("emergencyStop", description="e-stop")]), after=1.0
    )

    assert dispatcher.mission.node_status["r"] == {"state": MissionState.FAILED, "error_msg": "e-stop"}
    assert dispatcher.mission.state == MissionState.FAILED


def test_several_fatal_errors_are_joined_into_the_failure_reason() -> None:
    dispatcher = started()
    order = dispatcher.order

    dispatcher.step(
        on_order(
            order,
            0,
            errors=[error("a", description="one"), error("b", description="two", orderId=order.order_id)],
        ),
        after=1.0,
    )

    assert dispatcher.mission.failure_reason == "one\ntwo"


@pytest.mark.parametrize(
    "ignored",
    [
        pytest.param(error("lowSpeed", ErrorLevel.WARNING, "slow"), id="warning"),
        pytest.param(
            error("lowSpeed", ErrorLevel.WARNING, "slow", orderId="m1-n0-r0"), id="warning-on-order"
        ),
        pytest.param(error("blocked", ErrorLevel.FATAL, "old", orderId="m0-n3-r0"), id="fatal-other-order"),
        pytest.param(error("blocked", ErrorLevel.FATAL, "old", nodeId="m0-n3-r0-s2"), id="fatal-other-node"),
    ],
)
def test_warnings_and_fatal_errors_about_other_orders_are_ignored(ignored) -> None:
    dispatcher = started()

    result = dispatcher.step(on_order(dispatcher.order, 0, errors=[ignored]), after=1.0)

    assert (dispatcher.node("r"), dispatcher.mission.state, dispatcher.mission.failure_reason) == (
        MissionState.RUNNING,
        MissionState.RUNNING,
        None,
    )
    assert result.actions == []


def test_a_selector_recovers_from_a_failed_action_and_the_mission_completes() -> None:
    dispatcher = started(route("r0"), selector("s"), action("a", parent="s"), route("r", parent="s"))
    dispatcher.step(finished(dispatcher.order), after=1.0)
    assert dispatcher.mission.current_node == 2

    failed = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FAILED), after=1.0)
    assert (dispatcher.node("a"), dispatcher.node("r"), dispatcher.mission.current_node) == (
        MissionState.FAILED,
        MissionState.RUNNING,
        3,
    )
    assert [order.order_id for order in orders_sent(failed)] == ["m1-n3-r0"]
    assert dispatcher.mission.state == MissionState.RUNNING

    done = dispatcher.step(finished(dispatcher.order), after=1.0)
    assert (dispatcher.mission.state, dispatcher.node("s"), dispatcher.mission.failure_reason) == (
        MissionState.COMPLETED,
        MissionState.COMPLETED,
        None,
    )
    assert dispatcher.mission.node_status["a"]["error_msg"] == ACTION_FAILURE
    assert done.robot_state == RobotState.IDLE


def test_a_failed_leaf_in_a_sequence_fails_the_mission_and_skips_its_siblings() -> None:
    dispatcher = started(sequence("q"), action("a", parent="q"), route("r", parent="q"))

    result = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FAILED), after=1.0)

    ended = dispatcher.mission
    assert (ended.state, ended.failure_category, ended.failure_reason) == (
        MissionState.FAILED,
        FailureCategory.ROBOT_APP,
        ACTION_FAILURE,
    )
    assert (dispatcher.node("q"), dispatcher.node("r")) == (MissionState.FAILED, MissionState.PENDING)
    assert (ended.end_timestamp, ended.order) == (dispatcher.now, None)
    assert (result.robot_state, orders_sent(result)) == (RobotState.IDLE, [])


def test_the_next_leafs_order_waits_until_the_robot_is_idle() -> None:
    dispatcher = started(action("a"), route("r"))
    busy = on_order(
        dispatcher.order, 0, action_status=ActionStatus.FINISHED, extra_actions=[("x", ActionStatus.RUNNING)]
    )

    waiting = dispatcher.step(busy, after=1.0)
    assert (dispatcher.node("a"), dispatcher.node("r"), waiting.messages) == (
        MissionState.COMPLETED,
        MissionState.PENDING,
        [],
    )

    idle = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FINISHED), after=1.0)
    assert [order.order_id for order in orders_sent(idle)] == ["m1-n1-r0"]


def test_the_next_leafs_order_starts_where_the_robot_now_is() -> None:
    dispatcher = started(move("r1"), route("r2"))

    result = dispatcher.step(finished(dispatcher.order, pose=(5.0, 6.0, 0.0, "map")), after=1.0)

    [order] = orders_sent(result)
    assert (order.nodes[0].node_position.x, order.nodes[0].node_position.y) == (5.0, 6.0)


def test_the_next_leafs_order_waits_while_the_robot_is_offline() -> None:
    dispatcher = started(move("r1"), route("r2"))
    dispatcher.robot = replace(dispatcher.robot, online=False)

    result = dispatcher.step(finished(dispatcher.order), after=1.0)

    assert (dispatcher.node("r1"), dispatcher.node("r2"), result.messages) == (
        MissionState.COMPLETED,
        MissionState.PENDING,
        [],
    )


def test_a_mission_of_routes_in_a_selector_waits_for_the_cancel_of_a_failed_order_before_the_next() -> None:
    dispatcher = started(selector("s"), route("r1", parent="s"), route("r2", parent="s"))
    order = dispatcher.order
    fatal = error("blocked", ErrorLevel.FATAL, "path blocked", orderId=order.order_id)

    failed = dispatcher.step(on_order(order, 0, errors=[fatal]), after=1.0)
    [cancel] = cancel_actions(failed.actions)
    assert (dispatcher.node("r1"), dispatcher.node("r2"), orders_sent(failed)) == (
        MissionState.FAILED,
        MissionState.PENDING,
        [],
    )

    canceled = on_order(order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    idle = dispatcher.step(canceled.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)
    assert [o.order_id for o in orders_sent(idle)] == ["m1-n2-r0"]
    assert dispatcher.mission.state == MissionState.RUNNING


def test_a_failed_pause_order_does_not_leave_the_robot_in_teleop() -> None:
    dispatcher = started(action("p", PAUSE_ORDER))
    dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.RUNNING), after=1.0)

    result = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FAILED), after=1.0)

    assert dispatcher.mission.state == MissionState.FAILED
    assert result.robot_state == RobotState.IDLE
