"""Routes without stops: the next route leaf, certain to follow, sent ahead as an order update.

When the leaf that starts once a running route succeeds is a route too (`engine.next_leaf`, nothing that
can fail or branch between them), the step sends it right behind the route's own order, as an order update
that extends it at the route's last node; the robot drives on instead of stopping there for a new order.
Node states still change leaf by leaf. Every message is validated against each version's schema
(`checked_step`).
"""

from dataclasses import replace

import pytest

from dispatch.sent import SentOrder, sent_order
from dispatch.vocabulary import FailureCategory, Lifecycle, MissionState, RobotState
from tests.dispatch.builders import (
    NOW,
    Dispatcher,
    action,
    cancel_actions,
    error,
    finished,
    instant_actions_sent,
    mission,
    move,
    notify,
    on_order,
    orders_sent,
    robot_state,
    route,
    selector,
    sequence,
    started,
    wire,
)
from vda5050.models import ActionStatus, ErrorLevel, Map, MapStatus, OperatingMode, OrderContent
from vda5050.orders import check_order_graph, order_key

R1 = route("r1", (1.0, 0.0), (2.0, 0.0))
R2 = route("r2", (2.0, 3.0), (4.0, 3.0), allowedDeviationXY=0.0)
R3 = route("r3", (5.0, 5.0))


def sent(dispatcher: Dispatcher) -> SentOrder:
    assert dispatcher.mission is not None and dispatcher.mission.order is not None
    return sent_order(dispatcher.mission.order)


def leaf_message(dispatcher: Dispatcher) -> OrderContent:
    """The running leaf's own message (a new order, or the update that brought it)."""
    return sent(dispatcher).message


def ahead(dispatcher: Dispatcher) -> OrderContent:
    update = sent(dispatcher).ahead
    assert update is not None
    return update


def on_base(dispatcher: Dispatcher, reached: int, **fields) -> object:
    """The robot on the running leaf's message, without the update sent ahead."""
    return on_order(leaf_message(dispatcher), reached, **fields)


def idle_at_end_of_leaf(dispatcher: Dispatcher, **fields) -> object:
    """The robot stopped at the running leaf's last node, never having taken the update."""
    return finished(leaf_message(dispatcher), **fields)


# --- what is sent ahead ----------------------------------------------------------------------------------


def test_the_next_route_is_sent_ahead_right_behind_the_first_order() -> None:
    dispatcher = Dispatcher(mission(R1, R2))

    result = dispatcher.step(robot_state())

    first, update = orders_sent(result)
    assert (update.order_id, first.order_update_id, update.order_update_id) == (first.order_id, 0, 1)
    assert update.nodes[0] == first.nodes[-1]  # the decision point: same nodeId, sequenceId, content
    assert [n.sequence_id for n in update.nodes] == [4, 6, 8]
    assert [e.sequence_id for e in update.edges] == [5, 7]
    assert [n.node_id for n in update.nodes] == ["m1-n0-r0-s4", "m1-n1-r0-s6", "m1-n1-r0-s8"]
    assert [(n.node_position.x, n.node_position.y) for n in update.nodes[1:]] == [(2.0, 3.0), (4.0, 3.0)]
    assert check_order_graph(update) == []
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.RUNNING, MissionState.PENDING)
    assert dispatcher.mission.attempts == {"r1": 1, "r2": 1}
    assert (dispatcher.mission.order_accepted, dispatcher.mission.order_sent_at) == (False, NOW)
    stored = dispatcher.order
    assert (stored.order_id, stored.order_update_id) == (first.order_id, 1)
    assert (sent(dispatcher).message, sent(dispatcher).ahead) == (first, update)


@pytest.mark.parametrize(
    "tree",
    [
        pytest.param([R1, action("a"), R2], id="an action between"),
        pytest.param([R1, notify("n"), R2], id="a notify between"),
        pytest.param([R1, move("m")], id="a move next"),
        pytest.param([move("m"), R2], id="a move before"),
        pytest.param([action("a"), R2], id="an action before"),
        pytest.param([selector("s"), route("r1", parent="s"), route("r2", parent="s")], id="a fallback"),
        pytest.param([R1], id="no next leaf"),
        pytest.param([R1, {"name": "k", "parent": "root", "constant": {"success": False}}, R2], id="fails"),
    ],
)
def test_nothing_is_sent_ahead_unless_a_route_is_certain_to_follow_a_route(tree) -> None:
    dispatcher = Dispatcher(mission(*tree))

    result = dispatcher.step(robot_state())

    assert [o.order_update_id for o in orders_sent(result)] == [0]
    assert sent(dispatcher).ahead is None


def test_a_route_after_a_route_in_a_nested_sequence_is_sent_ahead() -> None:
    dispatcher = Dispatcher(
        mission(selector("s"), sequence("q", "s"), route("a", parent="q"), route("b", parent="q"), R3)
    )

    result = dispatcher.step(robot_state())

    assert [o.order_update_id for o in orders_sent(result)] == [0, 1]
    assert order_key(ahead(dispatcher).nodes[-1].node_id).node_index == 3


def _maps(hall: MapStatus) -> list[Map]:
    return [
        Map(map_id="map", map_version="1", map_status=MapStatus.ENABLED),
        Map(map_id="hall", map_version="1", map_status=hall),
    ]


def _r1_running_while_r2s_map_is_disabled() -> Dispatcher:
    """r1 started after an action, once the map r2 needs was disabled: r2 is not sent ahead."""
    dispatcher = started(action("a"), R1, route("r2", (3.0, 3.0), map_id="hall"))
    done = on_order(dispatcher.order, 0, action_status=ActionStatus.FINISHED)
    result = dispatcher.step(done.model_copy(update={"maps": _maps(MapStatus.DISABLED)}), after=1.0)
    assert [o.order_update_id for o in orders_sent(result)] == [0]
    assert (dispatcher.node("r1"), sent(dispatcher).ahead) == (MissionState.RUNNING, None)
    return dispatcher


def test_a_route_on_a_map_the_robot_has_not_enabled_is_sent_ahead_once_it_is() -> None:
    dispatcher = _r1_running_while_r2s_map_is_disabled()

    later = dispatcher.step(on_base(dispatcher, 2).model_copy(update={"maps": _maps(MapStatus.ENABLED)}))

    assert [o.order_update_id for o in orders_sent(later)] == [1]


def test_nothing_is_sent_ahead_to_a_robot_offline_or_not_taking_orders() -> None:
    dispatcher = _r1_running_while_r2s_map_is_disabled()
    state = on_base(dispatcher, 2).model_copy(update={"maps": _maps(MapStatus.ENABLED)})

    dispatcher.robot = replace(dispatcher.robot, online=False)
    offline = dispatcher.step(state, after=1.0)
    dispatcher.robot = replace(dispatcher.robot, online=True)
    manual = dispatcher.step(state.model_copy(update={"operating_mode": OperatingMode.MANUAL}), after=1.0)

    assert orders_sent(offline) == orders_sent(manual) == []
    assert [o.order_update_id for o in orders_sent(dispatcher.step(state, after=1.0))] == [1]


# --- leaf by leaf ----------------------------------------------------------------------------------------


def test_node_states_change_leaf_by_leaf_as_the_robot_drives_on() -> None:
    dispatcher = started(R1, R2)
    base, update = leaf_message(dispatcher), ahead(dispatcher)
    both = dispatcher.order

    on_r1 = dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    assert (dispatcher.node("r1"), dispatcher.node("r2"), dispatcher.mission.current_node) == (
        MissionState.RUNNING,
        MissionState.PENDING,
        0,
    )
    assert (dispatcher.mission.order_accepted, on_r1.messages) == (True, [])

    at_end_of_r1 = dispatcher.step(on_order(both, 4, driving=True), after=1.0)
    assert (dispatcher.node("r1"), dispatcher.node("r2"), dispatcher.mission.current_node) == (
        MissionState.COMPLETED,
        MissionState.RUNNING,
        1,
    )
    assert at_end_of_r1.messages == []  # r2 runs on the update the robot holds
    assert (sent(dispatcher).message, sent(dispatcher).ahead) == (update, None)
    assert dispatcher.mission.task_status == {"r1": 0, "r2": 0}
    assert base.nodes[-1].sequence_id == 4

    dispatcher.step(on_order(both, 6, driving=True), after=1.0)
    assert (dispatcher.node("r2"), dispatcher.mission.task_status) == (
        MissionState.RUNNING,
        {"r1": 0, "r2": 1},
    )

    done = dispatcher.step(finished(both), after=1.0)
    assert (dispatcher.mission.state, dispatcher.node("r2"), dispatcher.mission.task_status) == (
        MissionState.COMPLETED,
        MissionState.COMPLETED,
        {"r1": 0, "r2": 2},
    )
    assert (done.messages, done.robot_state) == ([], RobotState.IDLE)


def test_a_state_past_the_end_of_the_first_route_completes_it_and_follows_the_next() -> None:
    dispatcher = started(R1, R2)

    dispatcher.step(on_order(dispatcher.order, 6, driving=True), after=1.0)

    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)
    assert dispatcher.mission.task_status == {"r1": 0, "r2": 1}


def test_a_robot_done_with_both_routes_in_one_state_completes_the_mission_passing_the_second_running() -> (
    None
):
    """The robot drove both routes before a step saw the first end: the second is still seen RUNNING."""
    dispatcher = started(R1, R2)

    result = dispatcher.step(finished(dispatcher.order), after=1.0)

    assert dispatcher.mission.state == MissionState.COMPLETED
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.COMPLETED)
    [passed] = result.passed
    assert (passed.state, passed.current_node) == (MissionState.RUNNING, 1)
    assert {leaf: passed.node_status[leaf]["state"] for leaf in ("r1", "r2")} == {
        "r1": MissionState.COMPLETED,
        "r2": MissionState.RUNNING,
    }


def test_a_step_that_sees_the_next_route_start_passes_through_nothing() -> None:
    dispatcher = started(R1, R2)

    result = dispatcher.step(on_order(dispatcher.order, 4, driving=True), after=1.0)

    assert (dispatcher.node("r2"), result.passed) == (MissionState.RUNNING, [])


def test_the_route_after_next_is_sent_ahead_once_the_next_one_runs() -> None:
    dispatcher = started(R1, R2, R3)
    held = dispatcher.order
    second = ahead(dispatcher)

    result = dispatcher.step(on_order(held, 4, driving=True), after=1.0)

    [third] = orders_sent(result)
    assert (third.order_id, third.order_update_id) == (second.order_id, 2)
    assert third.nodes[0] == second.nodes[-1]
    assert [n.sequence_id for n in third.nodes] == [8, 10]
    assert third.nodes[1].node_id == "m1-n2-r0-s10"
    assert (dispatcher.node("r2"), dispatcher.node("r3")) == (MissionState.RUNNING, MissionState.PENDING)
    assert (sent(dispatcher).message, sent(dispatcher).ahead) == (second, third)

    dispatcher.step(on_order(dispatcher.order, 8, driving=True), after=1.0)
    assert (dispatcher.node("r2"), dispatcher.node("r3"), dispatcher.mission.current_node) == (
        MissionState.COMPLETED,
        MissionState.RUNNING,
        2,
    )
    dispatcher.step(finished(dispatcher.order), after=1.0)
    assert dispatcher.mission.state == MissionState.COMPLETED


# --- an update the robot refuses or lacks ----------------------------------------------------------------


@pytest.mark.parametrize("error_type", ["orderUpdateError", "OUTDATED_ORDER_UPDATE", "validationError"])
def test_a_refused_update_is_dropped_and_the_next_route_gets_an_order_of_its_own(error_type: str) -> None:
    dispatcher = started(R1, R2)
    base, update = leaf_message(dispatcher), ahead(dispatcher)
    refusal = error(
        error_type, ErrorLevel.WARNING, "no", orderId=base.order_id, orderUpdateId=str(update.order_update_id)
    )

    refused = dispatcher.step(on_order(base, 2, errors=[refusal], driving=True), after=1.0)
    assert refused.rejected
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.RUNNING, MissionState.PENDING)
    assert dispatcher.mission.order_accepted is True
    assert (sent(dispatcher).message, sent(dispatcher).ahead) == (base, None)
    assert orders_sent(refused) == []

    later = dispatcher.step(on_order(base, 2, errors=[refusal], driving=True), after=5.0)
    assert orders_sent(later) == []  # never re-sent, never sent ahead again

    done = dispatcher.step(finished(base, errors=[refusal]), after=1.0)
    [own] = orders_sent(done)
    assert (own.order_id, own.order_update_id) == ("m1-n1-r1", 0)
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)


def test_a_robot_that_stopped_at_the_end_of_the_route_without_the_update_gets_it_again_identically() -> None:
    dispatcher = started(R1, R2)
    update = ahead(dispatcher)
    stopped = idle_at_end_of_leaf(dispatcher)

    waiting = dispatcher.step(stopped, after=2.0)  # the resend period (3 s) has not passed
    assert (dispatcher.node("r1"), dispatcher.node("r2"), waiting.messages) == (
        MissionState.COMPLETED,
        MissionState.PENDING,
        [],
    )

    again = dispatcher.step(stopped, after=1.5)
    assert [wire(o) for o in orders_sent(again)] == [wire(update)]
    assert (sent(dispatcher).ahead, dispatcher.mission.order_sent_at) == (update, dispatcher.now)
    assert dispatcher.node("r2") == MissionState.PENDING

    took_it = dispatcher.step(on_order(dispatcher.order, 4, driving=True), after=0.2)
    assert (dispatcher.node("r2"), orders_sent(took_it)) == (MissionState.RUNNING, [])


def test_a_robot_that_took_the_update_after_a_late_state_without_it_runs_the_next_route_on_it() -> None:
    """CI, beat SIGKILLed mid-mission on a starved machine: the robot reported the first route's end
    without the update more than a second after it was sent, then took it. The next route ran on that
    update alone: no order of its own beside it (which a robot driving the update refuses as busy)."""
    dispatcher = started(R1, R2)
    stopped = idle_at_end_of_leaf(dispatcher)

    late = dispatcher.step(stopped, after=2.0)  # arrived 2 s after the update was sent
    assert orders_sent(late) == []

    held = dispatcher.step(on_order(dispatcher.order, 4, driving=True), after=0.1)
    done = dispatcher.step(finished(dispatcher.order), after=1.0)
    assert orders_sent(held) + orders_sent(done) == []
    assert (dispatcher.node("r2"), dispatcher.mission.state) == (
        MissionState.COMPLETED,
        MissionState.COMPLETED,
    )


def test_a_resent_update_the_robot_refuses_gives_the_next_route_an_order_of_its_own() -> None:
    dispatcher = started(R1, R2)
    base, update = leaf_message(dispatcher), ahead(dispatcher)
    dispatcher.step(idle_at_end_of_leaf(dispatcher), after=3.5)  # re-sent
    refusal = error(
        "orderUpdateError",
        ErrorLevel.WARNING,
        "no",
        orderId=base.order_id,
        orderUpdateId=str(update.order_update_id),
    )

    result = dispatcher.step(idle_at_end_of_leaf(dispatcher, errors=[refusal]), after=0.2)

    [own] = orders_sent(result)
    assert (own.order_id, own.order_update_id, result.rejected) == ("m1-n1-r1", 0, True)
    assert (dispatcher.node("r2"), sent(dispatcher).ahead) == (MissionState.RUNNING, None)


def test_a_robot_no_longer_on_the_order_the_update_extends_gets_an_order_for_the_next_route() -> None:
    """A robot restarted after the first route, holding no order: no update can extend what it lacks."""
    dispatcher = started(R1, R2)
    dispatcher.step(idle_at_end_of_leaf(dispatcher), after=0.5)  # the first route is done

    result = dispatcher.step(robot_state(last_node_sequence_id=0), after=0.2)

    [own] = orders_sent(result)
    assert own.order_id == "m1-n1-r1"
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)
    assert sent(dispatcher).ahead is None


def test_a_state_too_early_to_tell_whether_the_robot_got_the_update_leaves_the_next_route_waiting() -> None:
    dispatcher = started(R1, R2)
    stopped = idle_at_end_of_leaf(dispatcher)

    early = dispatcher.step(stopped, after=0.5)
    assert (dispatcher.node("r1"), dispatcher.node("r2"), early.messages) == (
        MissionState.COMPLETED,
        MissionState.PENDING,
        [],
    )

    took_it = dispatcher.step(on_order(dispatcher.order, 4), after=0.1)
    assert (dispatcher.node("r2"), took_it.messages) == (MissionState.RUNNING, [])


def test_an_unacknowledged_update_is_re_sent_identically_while_the_robot_drives_the_route() -> None:
    dispatcher = started(R1, R2)
    update = ahead(dispatcher)

    result = dispatcher.step(on_base(dispatcher, 2, driving=True), after=4.0)

    [again] = orders_sent(result)
    assert wire(again) == wire(update)
    assert dispatcher.mission.order_sent_at == dispatcher.now


def test_a_robot_that_lacks_the_first_order_gets_it_again_and_the_update_right_behind_it() -> None:
    dispatcher = started(R1, R2)
    base, update = leaf_message(dispatcher), ahead(dispatcher)

    result = dispatcher.step(robot_state(), after=4.0)

    assert [wire(order) for order in orders_sent(result)] == [wire(base), wire(update)]
    assert (sent(dispatcher).message, sent(dispatcher).ahead) == (base, update)
    assert dispatcher.mission.order_accepted is False


def test_a_first_sending_delivered_late_beside_the_resend_runs_the_next_route_once() -> None:
    """Fault suite seed 964301: the broker delivered the first order and its update late, right before
    the resend; the robot took both and answered the resent order with an orderUpdateError about it."""
    dispatcher = started(R1, R2)
    base = leaf_message(dispatcher)
    dispatcher.step(robot_state(), after=4.0)  # both re-sent
    late = error("orderUpdateError", ErrorLevel.WARNING, "lower", orderId=base.order_id, orderUpdateId=str(0))

    holding = dispatcher.step(on_order(dispatcher.order, 2, errors=[late], driving=True), after=1.0)
    assert not holding.rejected
    assert dispatcher.mission.order_accepted is True

    on_r2 = dispatcher.step(on_order(dispatcher.order, 6, errors=[late], driving=True), after=1.0)
    assert orders_sent(on_r2) == []  # r2 runs on the update the robot holds: no order of its own
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)

    done = dispatcher.step(finished(dispatcher.order, errors=[late]), after=1.0)
    assert (orders_sent(done), dispatcher.mission.state) == ([], MissionState.COMPLETED)


def test_a_refused_first_order_fails_its_leaf_as_before() -> None:
    dispatcher = started(R1, R2)
    base = leaf_message(dispatcher)
    refusal = error("orderError", ErrorLevel.WARNING, "far away", orderId=base.order_id, orderUpdateId="0")

    result = dispatcher.step(robot_state(errors=[refusal]), after=1.0)

    assert result.rejected
    assert (dispatcher.mission.state, dispatcher.node("r1"), dispatcher.node("r2")) == (
        MissionState.FAILED,
        MissionState.FAILED,
        MissionState.PENDING,
    )


# --- failures, cancel, timeout, route updates ---------------------------------------------------------------


def test_a_robot_failing_on_the_next_route_fails_that_leaf() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.step(on_order(both, 4, driving=True), after=1.0)
    fatal = error("blocked", ErrorLevel.FATAL, "path blocked", nodeId=both.nodes[-1].node_id)

    result = dispatcher.step(on_order(both, 6, errors=[fatal]), after=1.0)

    assert (dispatcher.node("r1"), dispatcher.node("r2"), dispatcher.mission.state) == (
        MissionState.COMPLETED,
        MissionState.FAILED,
        MissionState.FAILED,
    )
    assert dispatcher.mission.node_status["r2"]["error_msg"] == "path blocked"
    [cancel] = cancel_actions(result.actions)
    assert cancel.action_id.startswith(f"{both.order_id}-cancel")


def test_a_robot_failing_on_the_first_route_fails_it_and_cancels_the_whole_order() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    fatal = error("blocked", ErrorLevel.FATAL, "path blocked", orderId=both.order_id)

    result = dispatcher.step(on_order(both, 2, errors=[fatal]), after=1.0)

    assert (dispatcher.node("r1"), dispatcher.node("r2"), dispatcher.mission.state) == (
        MissionState.FAILED,
        MissionState.PENDING,
        MissionState.FAILED,
    )
    assert len(cancel_actions(result.actions)) == 1


@pytest.mark.parametrize("held", [True, False], ids=["update-held", "update-not-yet-held"])
def test_cancel_in_the_middle_of_an_extended_order_stops_it_all(held: bool) -> None:
    dispatcher = started(R1, R2)
    both, base = dispatcher.order, leaf_message(dispatcher)
    driving = on_order(both if held else base, 2, driving=True)
    dispatcher.step(driving, after=1.0)
    dispatcher.mission.needs_canceled = True

    asked = dispatcher.step(driving, after=5.0)  # past the resend period: nothing is re-sent now
    [cancel] = cancel_actions(asked.actions)
    assert [(a.action_type, a.action_id) for a in instant_actions_sent(asked)] == [
        ("cancelOrder", cancel.action_id)
    ]
    assert cancel.action_id.startswith(f"{both.order_id}-cancel")
    assert orders_sent(asked) == []

    waiting = dispatcher.step(driving, after=5.0)
    assert orders_sent(waiting) == []  # 3.0: no order update after cancelOrder
    stopped = on_order(both if held else base, 2, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    dispatcher.step(stopped.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)
    assert (dispatcher.mission.state, dispatcher.node("r1"), dispatcher.node("r2")) == (
        MissionState.CANCELED,
        MissionState.CANCELED,
        MissionState.PENDING,
    )
    assert dispatcher.mission.failure_category == FailureCategory.CANCELED


def test_cancel_once_the_next_route_runs_cancels_that_one() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.step(on_order(both, 6, driving=True), after=1.0)
    dispatcher.mission.needs_canceled = True

    asked = dispatcher.step(on_order(both, 6, driving=True), after=1.0)
    [cancel] = cancel_actions(asked.actions)
    stopped = on_order(both, 6, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    dispatcher.step(stopped.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)

    assert (dispatcher.mission.state, dispatcher.node("r1"), dispatcher.node("r2")) == (
        MissionState.CANCELED,
        MissionState.COMPLETED,
        MissionState.CANCELED,
    )


def test_cancel_while_the_update_may_still_reach_a_stopped_robot_asks_for_cancel_order() -> None:
    dispatcher = started(R1, R2)
    dispatcher.mission.needs_canceled = True

    result = dispatcher.step(idle_at_end_of_leaf(dispatcher), after=0.5)

    assert len(cancel_actions(result.actions)) == 1
    assert dispatcher.mission.state == MissionState.RUNNING


def test_a_cancel_the_robot_refuses_by_error_only_still_ends_the_mission() -> None:
    """Compatibility rule cancel_refused_by_error_only (vda-5050-lib 1.4.0) with an update sent ahead."""
    dispatcher = started(R1, R2)
    dispatcher.mission.needs_canceled = True
    stopped = idle_at_end_of_leaf(dispatcher)
    [cancel] = cancel_actions(dispatcher.step(stopped, after=0.5).actions)

    refusal = error("noOrderToCancel", ErrorLevel.WARNING, "no order", actionId=cancel.action_id)
    result = dispatcher.step(finished(leaf_message(dispatcher), errors=[refusal]), after=1.0)

    assert dispatcher.mission.state == MissionState.CANCELED
    assert [rule for rule, _ in result.rules_applied] == ["cancel_refused_by_error_only"]


def test_a_running_mission_deleted_with_an_extended_order_is_canceled_then_deleted() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.mission.needs_canceled = True
    dispatcher.mission.lifecycle = Lifecycle.PENDING_DELETE

    asked = dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    [cancel] = cancel_actions(asked.actions)
    stopped = on_order(both, 2, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    result = dispatcher.step(stopped.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)

    assert (dispatcher.mission.state, result.delete_mission) == (MissionState.CANCELED, True)


def test_a_timeout_with_an_extended_order_cancels_it() -> None:
    dispatcher = started(R1, R2, timeout=10.0)
    both = dispatcher.order

    result = dispatcher.step(on_order(both, 2, driving=True), after=11.0)

    assert (dispatcher.mission.state, dispatcher.mission.failure_category) == (
        MissionState.FAILED,
        FailureCategory.TIMEOUT,
    )
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.FAILED, MissionState.PENDING)
    assert [a.action_type for a in instant_actions_sent(result)] == ["cancelOrder"]
    assert orders_sent(result) == []


def test_a_route_update_of_the_route_sent_ahead_restarts_it_once_it_runs() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    dispatcher.mission.update_nodes = {
        "r2": {"waypoints": [{"x": 9.0, "y": 9.0, "theta": 0.0, "map_id": "map"}]}
    }

    before = dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    assert (before.actions, dispatcher.node("r2")) == ([], MissionState.PENDING)  # r1 drives on undisturbed

    takes_over = dispatcher.step(on_order(both, 4, driving=True), after=1.0)
    assert dispatcher.node("r2") == MissionState.RUNNING
    [cancel] = cancel_actions(takes_over.actions)
    stopped = on_order(both, 4, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    resent = dispatcher.step(stopped.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)
    [own] = orders_sent(resent)
    assert own.order_id == "m1-n1-r1"
    assert (own.nodes[-1].node_position.x, own.nodes[-1].node_position.y) == (9.0, 9.0)


def test_a_route_update_of_the_running_route_restarts_it_and_the_next_gets_its_own_order() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    dispatcher.mission.update_nodes = {
        "r1": {"waypoints": [{"x": 7.0, "y": 0.0, "theta": 0.0, "map_id": "map"}]}
    }

    asked = dispatcher.step(on_order(both, 2, driving=True), after=1.0)
    [cancel] = cancel_actions(asked.actions)
    assert orders_sent(asked) == []
    stopped = on_order(both, 2, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)])
    restarted = dispatcher.step(stopped.model_copy(update={"node_states": [], "edge_states": []}), after=1.0)

    [own] = orders_sent(restarted)  # r2 was sent ahead once: it is not sent ahead again
    assert own.order_id == "m1-n0-r1"
    assert sent(dispatcher).ahead is None
    dispatcher.step(finished(dispatcher.order), after=1.0)
    assert [o.order_id for o in orders_sent(dispatcher.results[-1])] == ["m1-n1-r1"]


def test_a_route_update_of_a_route_brought_by_an_update_is_detected() -> None:
    dispatcher = started(R1, R2)
    both = dispatcher.order
    dispatcher.step(on_order(both, 4, driving=True), after=1.0)

    unchanged = dict(R2["route"])
    dispatcher.mission.update_nodes = {"r2": unchanged}
    same = dispatcher.step(on_order(both, 4, driving=True), after=1.0)
    assert same.actions == []

    dispatcher.mission.update_nodes = {
        "r2": {"waypoints": [{"x": 1.0, "y": 1.0, "theta": 0.0, "map_id": "map"}]}
    }
    changed = dispatcher.step(on_order(both, 4, driving=True), after=1.0)
    assert len(cancel_actions(changed.actions)) == 1
