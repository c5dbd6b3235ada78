"""Notify leaves, timeouts, deadlines, cancel, delete and route updates of a running mission."""

from dataclasses import replace
from datetime import timedelta

import pytest

from dispatch import engine
from dispatch.ending import DEADLINE_PASSED, TIMED_OUT
from dispatch.records import ActionRecord
from dispatch.step import PAUSE_ORDER
from dispatch.vocabulary import FailureCategory, Lifecycle, MissionState, RobotState
from tests.dispatch.builders import (
    IDLE_STATE,
    NOW,
    Dispatcher,
    action,
    cancel_actions,
    finished,
    instant_actions_sent,
    mission,
    notify,
    on_order,
    orders_sent,
    route,
    started,
)
from vda5050.models import ActionStatus, ActionType
from vda5050.orders import order_key

# --- notify ----------------------------------------------------------------------------------------------


def test_a_notify_leaf_is_set_running_and_handed_to_the_caller() -> None:
    dispatcher = Dispatcher(mission(notify("n"), route("r")))

    result = dispatcher.step(IDLE_STATE)

    assert (result.notify, dispatcher.node("n"), dispatcher.node("r")) == (
        "n",
        MissionState.RUNNING,
        MissionState.PENDING,
    )
    assert (orders_sent(result), dispatcher.mission.order) == ([], None)
    assert result.robot_state == RobotState.ON_TASK


def test_a_running_notify_is_not_handed_over_twice() -> None:
    dispatcher = Dispatcher(mission(notify("n"), route("r")))
    dispatcher.step(IDLE_STATE)

    result = dispatcher.step(IDLE_STATE, after=10.0)

    assert (result.notify, result.messages) == (None, [])


def test_a_notify_completed_by_the_caller_starts_the_next_leafs_order() -> None:
    dispatcher = Dispatcher(mission(notify("n"), route("r")))
    dispatcher.step(IDLE_STATE)
    dispatcher.mission.node_status = engine.set_leaf_state(
        dispatcher.mission.node_status, "n", MissionState.COMPLETED
    )

    result = dispatcher.step(IDLE_STATE, after=1.0)

    assert [order.order_id for order in orders_sent(result)] == ["m1-n1-r0"]
    assert (dispatcher.node("r"), dispatcher.mission.current_node) == (MissionState.RUNNING, 1)


def test_a_notify_failed_by_the_caller_fails_the_mission() -> None:
    dispatcher = Dispatcher(mission(notify("n"), route("r")))
    dispatcher.step(IDLE_STATE)
    dispatcher.mission.node_status = engine.set_leaf_state(
        dispatcher.mission.node_status, "n", MissionState.FAILED, "Notify got HTTP 404"
    )

    result = dispatcher.step(IDLE_STATE, after=1.0)

    assert (dispatcher.mission.state, dispatcher.mission.failure_category) == (
        MissionState.FAILED,
        FailureCategory.ROBOT_APP,
    )
    assert (result.messages, result.robot_state) == ([], RobotState.IDLE)


# --- timeout and deadline --------------------------------------------------------------------------------


def test_a_mission_is_not_timed_out_just_before_its_timeout() -> None:
    dispatcher = started(timeout=10.0)

    dispatcher.step(on_order(dispatcher.order, 0), after=9.999)

    assert dispatcher.mission.state == MissionState.RUNNING


def test_a_timed_out_mission_fails_and_cancels_the_robots_active_order() -> None:
    dispatcher = started(timeout=10.0)
    order = dispatcher.order

    result = dispatcher.step(on_order(order, 0), after=10.0)

    ended = dispatcher.mission
    assert (ended.state, ended.failure_reason, ended.failure_category) == (
        MissionState.FAILED,
        TIMED_OUT,
        FailureCategory.TIMEOUT,
    )
    assert ended.node_status["r"] == {"state": MissionState.FAILED, "error_msg": TIMED_OUT}
    assert (ended.end_timestamp, ended.order) == (NOW + timedelta(seconds=10), None)
    [cancel] = cancel_actions(result.actions)
    assert (cancel.mission, cancel.action_id.startswith(f"{order.order_id}-cancel")) == ("m1", True)
    assert [a.action_id for a in instant_actions_sent(result)] == [cancel.action_id]
    assert (orders_sent(result), result.robot_state) == ([], RobotState.IDLE)


def test_a_timed_out_mission_whose_order_may_still_arrive_cancels_it() -> None:
    dispatcher = started(timeout=10.0)

    result = dispatcher.step(IDLE_STATE, after=10.0)

    assert dispatcher.mission.state == MissionState.FAILED
    assert len(cancel_actions(result.actions)) == 1


def test_a_timed_out_mission_with_the_robot_idle_on_its_order_sends_no_cancel() -> None:
    dispatcher = started(action("a"), timeout=10.0)

    result = dispatcher.step(on_order(dispatcher.order, 0), after=10.0)

    assert dispatcher.mission.state == MissionState.FAILED
    assert (result.actions, result.messages) == ([], [])


def test_a_timed_out_mission_on_a_notify_sends_no_cancel() -> None:
    dispatcher = Dispatcher(mission(notify("n"), timeout=10.0))
    dispatcher.step(IDLE_STATE)

    result = dispatcher.step(IDLE_STATE, after=10.0)

    assert (dispatcher.mission.state, dispatcher.mission.failure_category) == (
        MissionState.FAILED,
        FailureCategory.TIMEOUT,
    )
    assert dispatcher.mission.node_status["n"]["state"] == MissionState.FAILED
    assert (result.actions, result.messages) == ([], [])


def test_a_mission_times_out_while_the_robot_is_offline_without_sending_anything() -> None:
    dispatcher = started(timeout=10.0)
    dispatcher.robot = replace(dispatcher.robot, online=False)

    result = dispatcher.step(None, after=11.0)

    assert dispatcher.mission.state == MissionState.FAILED
    assert result.messages == []
    assert len(cancel_actions(result.actions)) == 1  # kept, sent once the robot is back


def test_a_running_mission_past_its_deadline_fails_with_deadline() -> None:
    dispatcher = started(deadline=NOW + timedelta(seconds=5))

    result = dispatcher.step(on_order(dispatcher.order, 0), after=5.0)

    ended = dispatcher.mission
    assert (ended.state, ended.failure_reason, ended.failure_category) == (
        MissionState.FAILED,
        DEADLINE_PASSED,
        FailureCategory.DEADLINE,
    )
    assert len(cancel_actions(result.actions)) == 1
    assert result.robot_state == RobotState.IDLE


# --- cancel and delete -----------------------------------------------------------------------------------


def _canceled(dispatcher: Dispatcher, **fields) -> Dispatcher:
    dispatcher.mission = replace(dispatcher.mission, needs_canceled=True, **fields)
    return dispatcher


def test_canceling_a_running_order_requests_cancel_order_and_waits_for_it() -> None:
    dispatcher = _canceled(started())
    order = dispatcher.order

    result = dispatcher.step(on_order(order, 0), after=1.0)

    [cancel] = cancel_actions(result.actions)
    assert (cancel.mission, cancel.sent_at, cancel.send_count) == ("m1", dispatcher.now, 1)
    assert [(a.action_type, a.action_id) for a in instant_actions_sent(result)] == [
        (ActionType.CANCEL_ORDER, cancel.action_id)
    ]
    assert (dispatcher.mission.state, dispatcher.node("r")) == (MissionState.RUNNING, MissionState.RUNNING)
    assert orders_sent(result) == []


def test_waiting_for_cancel_order_requests_no_second_one() -> None:
    dispatcher = _canceled(started())
    dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    result = dispatcher.step(on_order(dispatcher.order, 2), after=1.0)

    assert (result.messages, len(cancel_actions(result.actions))) == ([], 1)


@pytest.mark.parametrize("status", [ActionStatus.FINISHED, ActionStatus.FAILED])
def test_a_final_cancel_order_ends_the_mission_canceled(status: ActionStatus) -> None:
    dispatcher = _canceled(started(route("r1"), route("r2")))
    order = dispatcher.order
    [cancel] = cancel_actions(dispatcher.step(on_order(order, 0), after=1.0).actions)

    result = dispatcher.step(
        on_order(order, 0, extra_actions=[(cancel.action_id, status, ActionType.CANCEL_ORDER)]).model_copy(
            update={"node_states": [], "edge_states": []}
        ),
        after=1.0,
    )

    ended = dispatcher.mission
    assert (ended.state, ended.failure_category, ended.end_timestamp) == (
        MissionState.CANCELED,
        FailureCategory.CANCELED,
        dispatcher.now,
    )
    assert (dispatcher.node("r1"), dispatcher.node("r2"), ended.node_status["root"]["state"]) == (
        MissionState.CANCELED,
        MissionState.PENDING,
        MissionState.CANCELED,
    )
    assert (result.messages, result.robot_state, result.delete_mission) == ([], RobotState.IDLE, False)


def test_canceling_while_a_notify_runs_ends_the_mission_at_once() -> None:
    dispatcher = Dispatcher(mission(notify("n"), route("r")))
    dispatcher.step(IDLE_STATE)
    _canceled(dispatcher)

    result = dispatcher.step(IDLE_STATE, after=1.0)

    assert (dispatcher.mission.state, dispatcher.node("n")) == (MissionState.CANCELED, MissionState.CANCELED)
    assert (result.actions, result.messages, result.robot_state) == ([], [], RobotState.IDLE)


def test_canceling_after_the_robot_finished_its_order_ends_the_mission_at_once() -> None:
    dispatcher = _canceled(started(action("a"), route("r")))

    result = dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.FINISHED), after=1.0)

    assert dispatcher.mission.state == MissionState.CANCELED
    assert (result.actions, orders_sent(result)) == ([], [])


def test_a_mission_deleted_while_running_is_canceled_then_deleted() -> None:
    dispatcher = _canceled(started(), lifecycle=Lifecycle.PENDING_DELETE)
    order = dispatcher.order
    first = dispatcher.step(on_order(order, 0), after=1.0)
    [cancel] = cancel_actions(first.actions)
    assert first.delete_mission is False

    result = dispatcher.step(
        on_order(order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)]).model_copy(
            update={"node_states": [], "edge_states": []}
        ),
        after=1.0,
    )

    assert (dispatcher.mission.state, result.delete_mission, result.robot_state) == (
        MissionState.CANCELED,
        True,
        RobotState.IDLE,
    )


def test_a_mission_marked_for_deletion_is_deleted_when_it_ends() -> None:
    dispatcher = started()
    dispatcher.mission = replace(dispatcher.mission, lifecycle=Lifecycle.PENDING_DELETE)

    result = dispatcher.step(finished(dispatcher.order), after=1.0)

    assert (dispatcher.mission.state, result.delete_mission) == (MissionState.COMPLETED, True)


def test_a_robot_deleted_during_a_mission_fails_it_and_is_deleted_without_cancel_order() -> None:
    dispatcher = started()
    dispatcher.robot = replace(dispatcher.robot, lifecycle=Lifecycle.PENDING_DELETE)

    result = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    ended = dispatcher.mission
    assert (ended.state, ended.failure_category, ended.failure_reason) == (
        MissionState.FAILED,
        FailureCategory.ROBOT_APP,
        "Robot carter01 was deleted",
    )
    assert (result.delete_robot, result.actions, result.messages) == (True, [], [])


# --- route updates ---------------------------------------------------------------------------------------

NEW_WAYPOINTS = {"waypoints": [{"x": 9.0, "y": 9.5, "theta": 0.0, "map_id": "map"}]}


def test_an_update_of_a_pending_route_is_used_for_its_first_order() -> None:
    dispatcher = Dispatcher(mission(route("r", (5.0, 6.0)), update_nodes={"r": NEW_WAYPOINTS}))

    result = dispatcher.step(IDLE_STATE)

    [order] = orders_sent(result)
    assert (order.nodes[-1].node_position.x, order.nodes[-1].node_position.y) == (9.0, 9.5)
    assert order.order_id == "m1-n0-r0"


def test_an_update_of_a_later_route_does_not_disturb_the_running_one() -> None:
    dispatcher = started(route("r1"), route("r2", (5.0, 6.0)))
    dispatcher.mission = replace(dispatcher.mission, update_nodes={"r2": NEW_WAYPOINTS})

    running = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)
    assert (running.actions, running.messages) == ([], [])

    # r2 had gone ahead with its old waypoints, and the robot drove them: r2 starts over with the new ones.
    result = dispatcher.step(finished(dispatcher.order), after=1.0)
    [order] = orders_sent(result)
    assert (order.order_id, order.nodes[-1].node_position.x) == ("m1-n1-r1", 9.0)
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)


def test_an_update_equal_to_the_sent_route_changes_nothing() -> None:
    dispatcher = started(route("r", (5.0, 6.0)))
    same = {"waypoints": dispatcher.mission.mission_tree[0]["route"]["waypoints"]}
    dispatcher.mission = replace(dispatcher.mission, update_nodes={"r": same})

    result = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    assert (result.actions, result.messages, dispatcher.node("r")) == ([], [], MissionState.RUNNING)


def _updated_while_running() -> tuple[Dispatcher, ActionRecord]:
    """A running route updated after the robot accepted it; the step that asked to cancel it."""
    dispatcher = started(route("r", (5.0, 6.0)))
    dispatcher.step(on_order(dispatcher.order, 0), after=1.0)
    dispatcher.mission = replace(dispatcher.mission, update_nodes={"r": NEW_WAYPOINTS})
    result = dispatcher.step(on_order(dispatcher.order, 0), after=1.0)
    [cancel] = cancel_actions(result.actions)
    return dispatcher, cancel


def test_an_update_of_the_running_route_cancels_its_order_first() -> None:
    dispatcher, cancel = _updated_while_running()
    result = dispatcher.results[-1]

    assert cancel.action_id.startswith("m1-n0-r0-cancel")
    assert [a.action_id for a in instant_actions_sent(result)] == [cancel.action_id]
    assert (orders_sent(result), dispatcher.node("r"), dispatcher.mission.state) == (
        [],
        MissionState.RUNNING,
        MissionState.RUNNING,
    )


def test_an_updated_route_sends_nothing_until_the_cancel_is_confirmed() -> None:
    dispatcher, _ = _updated_while_running()

    result = dispatcher.step(on_order(dispatcher.order, 0, driving=True), after=4.0)

    assert (result.messages, dispatcher.node("r")) == ([], MissionState.RUNNING)


def _cancel_confirmed(dispatcher: Dispatcher, cancel: ActionRecord):
    return on_order(
        dispatcher.results[0].mission.order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)]
    ).model_copy(update={"node_states": [], "edge_states": []})


def test_an_updated_route_is_resent_as_a_new_order_as_soon_as_the_cancel_is_confirmed() -> None:
    dispatcher, cancel = _updated_while_running()

    result = dispatcher.step(_cancel_confirmed(dispatcher, cancel), after=1.0)

    assert [order.order_id for order in orders_sent(result)] == ["m1-n0-r1"]


def test_an_updated_route_is_resent_as_a_new_order_with_the_next_attempt() -> None:
    dispatcher, cancel = _updated_while_running()
    confirmed = _cancel_confirmed(dispatcher, cancel)

    orders = [order for _ in range(2) for order in orders_sent(dispatcher.step(confirmed, after=1.0))]

    [order] = orders
    assert order_key(order.order_id).attempt == 1
    assert (order.order_id, order.nodes[-1].node_position.x, order.nodes[-1].node_position.y) == (
        "m1-n0-r1",
        9.0,
        9.5,
    )
    assert (dispatcher.node("r"), dispatcher.mission.attempts) == (MissionState.RUNNING, {"r": 2})
    assert dispatcher.mission.order["orderId"] == "m1-n0-r1"


def test_the_stale_order_of_an_updated_route_is_never_sent_again() -> None:
    dispatcher, cancel = _updated_while_running()
    confirmed = _cancel_confirmed(dispatcher, cancel)
    for _ in range(2):
        dispatcher.step(confirmed, after=1.0)
    new_order = dispatcher.order

    later = [dispatcher.step(confirmed, after=5.0) for _ in range(3)]

    sent = [order.order_id for result in later for order in orders_sent(result)]
    assert set(sent) == {new_order.order_id}
    assert (
        dispatcher.step(finished(new_order), after=1.0) and dispatcher.mission.state == MissionState.COMPLETED
    )


def test_an_update_of_an_unaccepted_route_never_resends_the_stale_order() -> None:
    dispatcher = started(route("r", (5.0, 6.0)))
    dispatcher.mission = replace(dispatcher.mission, update_nodes={"r": NEW_WAYPOINTS})

    result = dispatcher.step(IDLE_STATE, after=5.0)

    assert orders_sent(result) == []
    assert len(cancel_actions(result.actions)) == 1


def test_a_canceled_mission_whose_robot_never_confirms_times_out() -> None:
    dispatcher = _canceled(started(timeout=10.0))
    dispatcher.step(on_order(dispatcher.order, 0), after=1.0)

    result = dispatcher.step(on_order(dispatcher.order, 0), after=9.0)

    assert (dispatcher.mission.state, dispatcher.mission.failure_category) == (
        MissionState.FAILED,
        FailureCategory.TIMEOUT,
    )
    assert len(cancel_actions(result.actions)) == 1  # the same cancelOrder, not a second one


def test_canceling_a_mission_during_pause_order_returns_the_robot_to_idle() -> None:
    dispatcher = _canceled(started(action("p", PAUSE_ORDER)))
    order = dispatcher.order
    running = dispatcher.step(on_order(order, 0, action_status=ActionStatus.RUNNING), after=1.0)
    [cancel] = cancel_actions(running.actions)
    assert running.robot_state == RobotState.TELEOP

    result = dispatcher.step(
        on_order(
            order,
            0,
            action_status=ActionStatus.FAILED,
            extra_actions=[(cancel.action_id, ActionStatus.FINISHED)],
        ),
        after=1.0,
    )

    assert dispatcher.mission.state == MissionState.CANCELED
    assert result.robot_state == RobotState.IDLE
