"""Robot-side faults (`dispatch.faults`): a robot that lost its order (it restarted) and one that took an
order or an order update and does not execute it; and every case that is neither."""

from collections.abc import Callable, Iterator
from dataclasses import replace
from datetime import timedelta

import hypothesis
import pytest
from hypothesis import strategies as st

from dispatch import faults
from dispatch.records import DispatchSettings
from dispatch.sent import sent_order
from dispatch.vocabulary import MissionState, RobotState
from tests.dispatch.builders import (
    NOW,
    POSE,
    SETTINGS,
    Dispatcher,
    action,
    cancel_actions,
    error,
    finished,
    instant_action,
    instant_actions_sent,
    mission,
    on_order,
    orders_sent,
    robot_state,
    robot_view,
    route,
    selector,
)
from vda5050 import compat
from vda5050.models import ActionStatus, ActionType, ErrorLevel, OperatingMode, OrderContent, State

STALL = timedelta(seconds=30)
STALL_SETTINGS = replace(SETTINGS, order_stall=STALL)
R1 = route("r1", (1.0, 0.0), (2.0, 0.0), (3.0, 0.0))
R2 = route("r2", (3.0, 3.0))
RESTARTED = robot_state(header_id=0)  # a fresh process: no order, headerIds from 0


def waypoints(order: OrderContent) -> list[tuple[float, float]]:
    return [(n.node_position.x, n.node_position.y) for n in order.nodes[1:]]


def on_first_route(settings: DispatchSettings = STALL_SETTINGS) -> Dispatcher:
    """A two-route mission whose robot took the first route's order with the second sent ahead, and reached
    the first route's first waypoint (sequenceId 2)."""
    dispatcher = Dispatcher(mission(R1, R2), settings=settings)
    dispatcher.step(robot_state())
    dispatcher.step(on_order(dispatcher.order, 2), after=1.0)
    assert dispatcher.mission.order_accepted and dispatcher.order.order_update_id == 1
    return dispatcher


def canceled(order: OrderContent, reached: int, cancel_id: str) -> State:
    """The robot that canceled `order` at the node with sequenceId `reached`, confirming the cancel."""
    state = on_order(order, reached, extra_actions=[(cancel_id, ActionStatus.FINISHED)])
    return state.model_copy(update={"node_states": [], "edge_states": []})


# --- the robot lost its order ---------------------------------------------------------------------------


def test_a_robot_that_restarts_on_a_route_gets_the_rest_of_it_as_a_new_order_and_the_next_route_its_own() -> (
    None
):
    dispatcher = on_first_route()

    result = dispatcher.step(RESTARTED, after=2.0)

    [resumed] = orders_sent(result)
    assert resumed.order_id == "m1-n0-r1"  # the leaf's next attempt
    assert (resumed.nodes[0].node_position.x, resumed.nodes[0].node_position.y) == POSE[:2]  # where it stands
    assert waypoints(resumed) == [(2.0, 0.0), (3.0, 0.0)]  # the waypoints not reached
    assert dispatcher.node("r1") == MissionState.RUNNING
    assert sent_order(dispatcher.mission.order).ahead is None  # the route sent ahead is dropped
    assert not cancel_actions(result.actions)

    dispatcher.step(on_order(resumed, 0), after=1.0)
    result = dispatcher.step(finished(resumed), after=5.0)

    [own] = orders_sent(result)
    assert own.order_id == "m1-n1-r1" and waypoints(own) == [(3.0, 3.0)]
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)


def test_a_restarted_robot_drives_only_the_rest_of_a_route_that_had_a_route_update() -> None:
    """The resumed order is the updated route's rest, not a stale one: no cancel, no drive from the start."""
    updated = {"waypoints": [{"x": x, "y": 1.0, "theta": 0.0, "map_id": "map"} for x in (1.0, 2.0, 3.0)]}
    dispatcher = Dispatcher(mission(R1, update_nodes={"r1": updated}), settings=STALL_SETTINGS)
    dispatcher.step(robot_state())
    dispatcher.step(on_order(dispatcher.order, 2), after=1.0)
    assert waypoints(dispatcher.order) == [(1.0, 1.0), (2.0, 1.0), (3.0, 1.0)]

    [resumed] = orders_sent(dispatcher.step(RESTARTED, after=2.0))
    assert waypoints(resumed) == [(2.0, 1.0), (3.0, 1.0)]

    result = dispatcher.step(on_order(resumed, 0), after=1.0)

    assert (orders_sent(result), cancel_actions(result.actions)) == ([], [])
    assert dispatcher.node("r1") == MissionState.RUNNING
    result = dispatcher.step(finished(resumed), after=5.0)
    assert dispatcher.node("r1") == MissionState.COMPLETED


def test_a_robot_that_restarts_during_a_running_action_fails_the_leaf_and_the_fallback_runs() -> None:
    dispatcher = Dispatcher(mission(selector("s"), action("a", parent="s"), route("f", parent="s")))
    dispatcher.step(robot_state())
    order_id = dispatcher.order.order_id
    dispatcher.step(on_order(dispatcher.order, 0, action_status=ActionStatus.RUNNING), after=1.0)

    result = dispatcher.step(RESTARTED, after=2.0)

    assert dispatcher.node("a") == MissionState.FAILED
    assert dispatcher.mission.node_status["a"]["error_msg"] == faults.lost_reason(order_id)
    assert "may or may not have run" in faults.lost_reason(order_id)
    [fallback] = orders_sent(result)
    assert fallback.order_id == "m1-n2-r0" and dispatcher.node("f") == MissionState.RUNNING
    assert dispatcher.mission.state == MissionState.RUNNING


def test_an_instant_action_a_restarted_robot_never_confirmed_is_sent_again() -> None:
    dispatcher = on_first_route()
    dispatcher.actions = [instant_action(ActionType.START_PAUSE, sent_at=dispatcher.now)]

    result = dispatcher.step(RESTARTED, after=SETTINGS.instant_action_resend.total_seconds())

    assert [a.action_type for a in instant_actions_sent(result)] == [ActionType.START_PAUSE]


def test_an_instant_action_a_restarted_robot_had_running_is_sent_again_at_once() -> None:
    dispatcher = on_first_route()
    pause = instant_action(ActionType.START_PAUSE, status=ActionStatus.RUNNING.value, sent_at=dispatcher.now)
    dispatcher.actions = [pause]

    holding = dispatcher.step(on_order(dispatcher.order, 2), after=2.0)
    assert instant_actions_sent(holding) == []  # a robot on an order may have dropped older action states
    late = dispatcher.step(RESTARTED, after=0.5, arrived_at=pause.sent_at + timedelta(seconds=0.5))
    assert instant_actions_sent(late) == []  # a state that may have left the robot before the action

    result = dispatcher.step(RESTARTED, after=0.5)

    assert [a.action_id for a in instant_actions_sent(result)] == [pause.action_id]
    assert dispatcher.step(RESTARTED, after=0.5).messages == []  # once; then after the resend period


NOT_LOST: dict[str, Callable[[Dispatcher], None]] = {
    # a state that may have left the robot before the order reached it
    "a late state": lambda d: d.step(
        RESTARTED, after=2.0, arrived_at=d.mission.order_sent_at + timedelta(seconds=0.5)
    ),
    "back with its order": lambda d: d.step(on_order(d.order, 2), after=20.0),
    "slow": lambda d: d.step(on_order(d.order, 2), after=25.0),
    "in teleop": lambda d: (
        setattr(d, "robot", replace(d.robot, state=RobotState.TELEOP)),
        d.step(RESTARTED),
    )[1],
    "in a manual mode": lambda d: d.step(robot_state(operating_mode=OperatingMode.MANUAL), after=2.0),
    "offline": lambda d: (setattr(d, "robot", replace(d.robot, online=False)), d.step(RESTARTED, after=2.0))[
        1
    ],
}


@pytest.mark.parametrize("case", NOT_LOST.values(), ids=NOT_LOST.keys())
def test_a_robot_that_may_still_hold_its_order_gets_no_new_one(case: Callable[[Dispatcher], None]) -> None:
    dispatcher = on_first_route(SETTINGS)
    order = dispatcher.mission.order

    case(dispatcher)

    assert not orders_sent(dispatcher.results[-1])
    assert dispatcher.mission.order == order and dispatcher.node("r1") == MissionState.RUNNING


def test_an_order_the_robot_never_took_is_sent_again_identically_not_anew() -> None:
    dispatcher = Dispatcher(mission(R1))
    [order] = orders_sent(dispatcher.step(robot_state()))

    result = dispatcher.step(RESTARTED, after=SETTINGS.order_resend.total_seconds())

    assert orders_sent(result) == [order]


# --- the robot took an order and does not execute it -------------------------------------------------------


def standing_on_the_first_waypoint() -> tuple[Dispatcher, OrderContent, State]:
    """A one-route mission whose robot took the order and stands at its first waypoint, a second ago."""
    dispatcher = Dispatcher(mission(R1), settings=STALL_SETTINGS)
    dispatcher.step(robot_state())
    still = on_order(dispatcher.order, 2)
    dispatcher.step(still, after=1.0)
    return dispatcher, dispatcher.order, still


def test_an_order_taken_and_not_executed_is_canceled_and_the_rest_sent_anew() -> None:
    dispatcher, order, still = standing_on_the_first_waypoint()
    assert not dispatcher.step(still, after=29.0).messages

    result = dispatcher.step(still, after=1.0)

    [cancel] = cancel_actions(result.actions)
    assert [a.action_type for a in instant_actions_sent(result)] == [ActionType.CANCEL_ORDER]
    assert not result.rules_applied  # the order itself stalled, not an update
    assert not orders_sent(dispatcher.step(still, after=1.0))  # waits for the cancel

    result = dispatcher.step(canceled(order, 2, cancel.action_id), after=1.0)

    [resumed] = orders_sent(result)
    assert resumed.order_id == "m1-n0-r1" and waypoints(resumed) == [(2.0, 0.0), (3.0, 0.0)]
    assert dispatcher.node("r1") == MissionState.RUNNING


def test_a_stalled_order_whose_cancel_the_robot_never_confirms_fails_its_leaf_after_another_period() -> None:
    dispatcher, order, still = standing_on_the_first_waypoint()
    dispatcher.step(still, after=30.0)
    assert cancel_actions(dispatcher.actions)
    assert dispatcher.mission.progress_seen_at == dispatcher.now  # beat's wake-up once the cancel is overdue

    dispatcher.step(still, after=29.0)  # the cancel re-sent, still unconfirmed: the leaf waits
    assert dispatcher.node("r1") == MissionState.RUNNING

    dispatcher.step(still, after=1.0)

    assert dispatcher.node("r1") == MissionState.FAILED and dispatcher.mission.progress_seen_at is None
    reason = faults.unconfirmed_reason(order.order_id, 0, 30)
    assert (
        dispatcher.mission.node_status["r1"]["error_msg"] == reason and "nor confirmed its cancel" in reason
    )


def test_a_stalled_action_fails_once_the_cancel_is_confirmed() -> None:
    dispatcher = Dispatcher(mission(action("a")), settings=STALL_SETTINGS)
    dispatcher.step(robot_state())
    order = dispatcher.order
    still = on_order(order, 0, action_status=ActionStatus.WAITING)
    dispatcher.step(still, after=1.0)
    [cancel] = cancel_actions(dispatcher.step(still, after=30.0).actions)

    dispatcher.step(canceled(order, 0, cancel.action_id), after=1.0)

    assert dispatcher.node("a") == MissionState.FAILED
    assert dispatcher.mission.state == MissionState.FAILED
    assert "showed no progress on it for 30 s" in dispatcher.mission.failure_reason


def test_an_update_sent_ahead_taken_and_not_executed_records_the_rule_and_the_route_goes_out_anew() -> None:
    """vda5050-sdk 0.2.0: it takes the update at the end of the first route and stands still."""
    dispatcher = Dispatcher(mission(R1, R2), settings=STALL_SETTINGS)
    dispatcher.step(robot_state())
    update = dispatcher.order
    still = on_order(update, 6)  # the first route's last node, the second route's node still to go
    dispatcher.step(still, after=1.0)
    assert (dispatcher.node("r1"), dispatcher.node("r2")) == (MissionState.COMPLETED, MissionState.RUNNING)

    result = dispatcher.step(still, after=30.0)

    [cancel] = cancel_actions(result.actions)
    [(rule, why)] = result.rules_applied
    assert rule == compat.Rule.ORDER_UPDATE_NOT_EXECUTED and "update 1" in why

    result = dispatcher.step(canceled(update, 6, cancel.action_id), after=1.0)

    [own] = orders_sent(result)
    assert own.order_id == "m1-n1-r1" and own.order_update_id == 0 and waypoints(own) == [(3.0, 3.0)]


def test_a_robot_with_the_rule_is_sent_no_route_ahead() -> None:
    dispatcher = Dispatcher(mission(R1, R2), robot=robot_view(routes_ahead=False))

    result = dispatcher.step(robot_state())

    [order] = orders_sent(result)
    assert order.order_update_id == 0 and dispatcher.node("r2") == MissionState.PENDING


def _action_running(d: Dispatcher) -> None:
    """A blocking action at a node of the route, running all along."""
    d.step(on_order(d.order, 2, extra_actions=[("lift-1", ActionStatus.RUNNING)]), after=1.0)
    d.step(on_order(d.order, 2, extra_actions=[("lift-1", ActionStatus.RUNNING)]), after=40.0)


def _variant(**fields) -> Callable[[Dispatcher], None]:
    return lambda d: d.step(on_order(d.order, 2, **fields), after=31.0)


def _in_teleop(d: Dispatcher) -> None:
    d.robot = replace(d.robot, state=RobotState.TELEOP)
    d.step(on_order(d.order, 2), after=31.0)


NOT_STALLED: dict[str, Callable[[Dispatcher], None]] = {
    "driving": _variant(driving=True),
    "paused": lambda d: d.step(on_order(d.order, 2).model_copy(update={"paused": True}), after=31.0),
    "in teleop": _in_teleop,
    "in a manual mode": _variant(operating_mode=OperatingMode.MANUAL),
    "reporting an error": _variant(errors=[error("obstacle", ErrorLevel.WARNING)]),
    "at a blocking action": _action_running,
    "slow": lambda d: (d.step(on_order(d.order, 4), after=20.0), d.step(on_order(d.order, 4), after=25.0))[1],
    "the check off": lambda d: (setattr(d, "settings", SETTINGS), d.step(on_order(d.order, 2), after=60.0))[
        1
    ],
}


@pytest.mark.parametrize("case", NOT_STALLED.values(), ids=NOT_STALLED.keys())
def test_a_robot_that_stands_still_for_a_reason_or_moves_is_not_canceled(
    case: Callable[[Dispatcher], None],
) -> None:
    dispatcher = on_first_route()

    case(dispatcher)

    assert not cancel_actions(dispatcher.actions)
    assert not any(r.messages for r in dispatcher.results[2:])
    assert dispatcher.node("r1") == MissionState.RUNNING


def test_the_progress_clock_restarts_with_every_node_reached() -> None:
    dispatcher = on_first_route()
    assert (dispatcher.mission.progress_seen_at, dispatcher.mission.progress["lastNodeSequenceId"]) == (
        NOW + timedelta(seconds=1),
        2,
    )

    dispatcher.step(on_order(dispatcher.order, 4), after=20.0)

    assert dispatcher.mission.progress_seen_at == NOW + timedelta(seconds=21)


# --- properties -------------------------------------------------------------------------------------------

R4 = route("r4", (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (4.0, 0.0))  # nodes 2, 4, 6, 8: a robot never ends it
EVENTS = ("progress", "still", "driving", "paused", "manual", "error", "action running", "early empty")
EXCUSED = frozenset({"driving", "paused", "manual", "error", "action running"})
PROPERTY_SETTINGS = hypothesis.settings(max_examples=150, derandomize=True, deadline=None, database=None)


def robot_events() -> st.SearchStrategy[list[tuple[float, str]]]:
    """Steps some seconds apart (beat may wake one at any time), each of a state of one kind."""
    return st.lists(st.tuples(st.integers(0, 40), st.sampled_from(EVENTS)), max_size=12)


def state_for(dispatcher: Dispatcher, kind: str, reached: int) -> State:
    order = dispatcher.order
    if kind == "early empty":
        return RESTARTED
    fields = {
        "driving": {"driving": True},
        "manual": {"operating_mode": OperatingMode.MANUAL},
        "error": {"errors": [error("obstacle", ErrorLevel.WARNING)]},
        "action running": {"extra_actions": [("lift-1", ActionStatus.RUNNING)]},
    }.get(kind, {})
    state = on_order(order, reached, **fields)
    return state.model_copy(update={"paused": True}) if kind == "paused" else state


def play(events: list[tuple[float, str]]) -> Iterator[tuple[Dispatcher, str, dict | None]]:
    """A robot on the first of two routes (the second sent ahead), through `events`: after each step, the
    dispatcher, the kind of state it stepped and the mission's progress before the step."""
    dispatcher = Dispatcher(mission(R4, R2), settings=STALL_SETTINGS)
    dispatcher.step(robot_state())
    reached = 0
    for after, kind in events:
        if dispatcher.mission.order is None:
            return  # the leaf failed: a cancel never confirmed for a stall period (`cancel_overdue`)
        if kind == "progress":
            reached = min(reached + 2, 6)
        arrived_at = dispatcher.mission.order_sent_at if kind == "early empty" else None
        progress_before = dispatcher.mission.progress
        dispatcher.step(state_for(dispatcher, kind, reached), after=after, arrived_at=arrived_at)
        yield dispatcher, kind, progress_before


@PROPERTY_SETTINGS
@hypothesis.given(robot_events())
def test_no_new_order_while_the_robot_holds_its_order(events: list[tuple[float, str]]) -> None:
    """Whatever the robot does while it holds its order (and confirms no cancel of it), the only orderId it
    is sent is the first one: no state that holds it, nor one that may predate it, makes a new order."""
    steps = list(play(events))

    if steps:
        results = steps[-1][0].results
        first = orders_sent(results[0])[0].order_id
        assert {order.order_id for result in results for order in orders_sent(result)} == {first}


@PROPERTY_SETTINGS
@hypothesis.given(robot_events())
def test_no_cancel_of_a_robot_that_made_progress_within_the_stall_period(
    events: list[tuple[float, str]],
) -> None:
    """A cancel comes only after a whole stall period in which no step saw the robot progress (a node
    reached) or stand still for a reason (driving, paused, manual mode, an error, a running action)."""
    last_progress = None
    for dispatcher, kind, progress_before in play(events):
        if cancel_actions(dispatcher.results[-1].actions):
            assert last_progress is not None and dispatcher.now - last_progress >= STALL
            return
        if kind in EXCUSED or dispatcher.mission.progress != progress_before:
            last_progress = dispatcher.now
