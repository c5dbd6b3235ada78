"""Properties of every step: repeating it changes nothing, inputs are never mutated, and the digest the
bridge wakes steps by covers what steps read (and not the pose) and tells a robot that only took an order."""

import copy
from collections.abc import Callable
from dataclasses import replace
from datetime import timedelta

import pytest

from dispatch.held import NO_FINISHED_ACTIONS, state_digest, takes_order_only
from dispatch.records import ActionRecord
from dispatch.sent import sent_order
from dispatch.step import PAUSE_ORDER, step
from dispatch.vocabulary import Lifecycle
from tests.dispatch.builders import (
    IDLE_STATE,
    NOW,
    SETTINGS,
    Dispatcher,
    action,
    cancel_actions,
    error,
    finished,
    instant_action,
    mission,
    notify,
    on_order,
    robot_state,
    robot_view,
    route,
    started,
)
from vda5050.models import ActionState, ActionStatus, ActionType, ErrorLevel, OperatingMode, State

# A scenario sets a dispatcher up and returns the state of the step under test and how much later it runs.
Scenario = Callable[[], tuple[Dispatcher, State, float]]
NEW_WAYPOINTS = {"waypoints": [{"x": 9.0, "y": 9.5, "theta": 0.0, "map_id": "map"}]}


def _queued(**fields) -> Scenario:
    return lambda: (Dispatcher(mission(**fields)), IDLE_STATE, 0.0)


def _on_running(tree, state_of: Callable[[Dispatcher], State], after: float = 1.0, **fields) -> Scenario:
    def scenario() -> tuple[Dispatcher, State, float]:
        dispatcher = started(*tree, **fields)
        return dispatcher, state_of(dispatcher), after

    return scenario


def _canceled(state_of: Callable[[Dispatcher], State]) -> Scenario:
    def scenario() -> tuple[Dispatcher, State, float]:
        dispatcher = started(route("r1"), route("r2"))
        dispatcher.mission = replace(dispatcher.mission, needs_canceled=True)
        return dispatcher, state_of(dispatcher), 1.0

    return scenario


def _cancel_confirmed(dispatcher: Dispatcher) -> State:
    order = dispatcher.order
    [cancel] = cancel_actions(dispatcher.step(on_order(order, 0), after=1.0).actions)
    return on_order(order, 0, extra_actions=[(cancel.action_id, ActionStatus.FINISHED)]).model_copy(
        update={"node_states": [], "edge_states": []}
    )


def _route_updated(confirm: bool) -> Scenario:
    def scenario() -> tuple[Dispatcher, State, float]:
        dispatcher = started(route("r", (5.0, 6.0)))
        accepted = on_order(dispatcher.order, 0)
        dispatcher.step(accepted, after=1.0)
        dispatcher.mission = replace(dispatcher.mission, update_nodes={"r": NEW_WAYPOINTS})
        if not confirm:
            return dispatcher, accepted, 1.0
        return dispatcher, _cancel_confirmed(dispatcher), 1.0

    return scenario


def _with_actions(*actions: ActionRecord, state: State = IDLE_STATE, **robot) -> Scenario:
    return lambda: (Dispatcher(None, robot=robot_view(**robot), actions=list(actions)), state, 0.0)


def _notify_started() -> tuple[Dispatcher, State, float]:
    return Dispatcher(mission(notify("n"), route("r"))), IDLE_STATE, 0.0


TELEOP_FINISHED = instant_action(ActionType.START_TELEOP, "teleop-1", sent_at=NOW)
SCENARIOS: dict[str, Scenario] = {
    "start": _queued(),
    "waiting-for-battery": lambda: (Dispatcher(mission()), robot_state(battery=3.0), 0.0),
    "deadline-before-start": _queued(deadline=NOW),
    "delete-before-start": _queued(lifecycle=Lifecycle.PENDING_DELETE),
    "resend-due": _on_running([route("r")], lambda d: IDLE_STATE, after=3.0),
    "accepted": _on_running([route("r", (1.0, 0.0), (2.0, 0.0))], lambda d: on_order(d.order, 0)),
    "progress": _on_running(
        [route("r", (1.0, 0.0), (2.0, 0.0), allowedDeviationXY=0.0)], lambda d: on_order(d.order, 2)
    ),
    "route-done-next-order": _on_running([route("r1"), action("a")], lambda d: finished(d.order)),
    "route-sent-ahead": lambda: (Dispatcher(mission(route("r1"), route("r2"))), IDLE_STATE, 0.0),
    "ahead-taken": _on_running([route("r1"), route("r2")], lambda d: on_order(d.order, 2)),
    "ahead-refused": _on_running(
        [route("r1"), route("r2")],
        lambda d: on_order(
            sent_order(d.mission.order).message,
            0,
            errors=[
                error("orderUpdateError", ErrorLevel.WARNING, orderId=d.order.order_id, orderUpdateId="1")
            ],
        ),
    ),
    "ahead-lacked": _on_running(
        [route("r1"), route("r2")],
        lambda d: finished(sent_order(d.mission.order).message),
        after=3.5,  # the update re-sent
    ),
    "mission-completed": _on_running([route("r")], lambda d: finished(d.order)),
    "rejected": _on_running(
        [route("r")], lambda d: robot_state(errors=[error("orderError", orderId=d.order.order_id)])
    ),
    "action-failed": _on_running(
        [action("a")], lambda d: on_order(d.order, 0, action_status=ActionStatus.FAILED)
    ),
    "fatal-error-cancel": _on_running(
        [route("r")],
        lambda d: on_order(d.order, 0, errors=[error("blocked", ErrorLevel.FATAL, orderId=d.order.order_id)]),
    ),
    "pause-order-teleop": _on_running(
        [action("p", PAUSE_ORDER), route("r")],
        lambda d: on_order(d.order, 0, action_status=ActionStatus.RUNNING),
    ),
    "timeout-cancel": _on_running([route("r")], lambda d: on_order(d.order, 0), after=301.0),
    "deadline-running": _on_running(
        [route("r")], lambda d: on_order(d.order, 0), after=5.0, deadline=NOW + timedelta(seconds=5)
    ),
    "cancel-requested": _canceled(lambda d: on_order(d.order, 0)),
    "cancel-confirmed": _canceled(_cancel_confirmed),
    "notify": _notify_started,
    "new-instant-actions": _with_actions(
        instant_action(ActionType.FACTSHEET_REQUEST), instant_action(ActionType.STOP_TELEOP)
    ),
    "instant-action-resend": _with_actions(
        instant_action(ActionType.FACTSHEET_REQUEST, sent_at=NOW - SETTINGS.instant_action_resend)
    ),
    "teleop-started": _with_actions(
        TELEOP_FINISHED, state=robot_state(action_states=[(TELEOP_FINISHED.action_id, ActionStatus.FINISHED)])
    ),
    "charging": _with_actions(state=robot_state(charging=True)),
    "manual-mode": lambda: (Dispatcher(mission()), robot_state(operating_mode=OperatingMode.MANUAL), 0.0),
    "route-update-cancel": _route_updated(confirm=False),
    "route-update-confirmed": _route_updated(confirm=True),
}


def _params() -> list:
    return [pytest.param(scenario, id=name) for name, scenario in SCENARIOS.items()]


@pytest.mark.parametrize("scenario", _params())
def test_repeating_a_step_with_its_own_results_sends_and_changes_nothing(scenario: Scenario) -> None:
    dispatcher, state, after = scenario()
    dispatcher.step(state, after=after)
    mission_after, actions_after, robot_after = (
        copy.deepcopy(dispatcher.mission),
        copy.deepcopy(dispatcher.actions),
        dispatcher.robot,
    )

    again = dispatcher.step(state)

    assert again.messages == []
    assert (again.notify, again.rejected) == (None, False)
    assert dispatcher.mission == mission_after
    assert dispatcher.actions == actions_after
    assert dispatcher.robot == robot_after


@pytest.mark.parametrize("scenario", _params())
def test_a_step_never_mutates_its_inputs(scenario: Scenario) -> None:
    dispatcher, state, after = scenario()
    mission_before, actions_before, state_before = (
        copy.deepcopy(dispatcher.mission),
        copy.deepcopy(dispatcher.actions),
        state.model_copy(deep=True),
    )

    result = step(
        now=dispatcher.now + timedelta(seconds=after),
        robot=dispatcher.robot,
        state=state,
        state_arrived_at=dispatcher.now + timedelta(seconds=after),
        mission=dispatcher.mission,
        actions=dispatcher.actions,
        settings=SETTINGS,
    )

    assert dispatcher.mission == mission_before
    assert dispatcher.actions == actions_before
    assert state == state_before
    assert result.mission is not dispatcher.mission or dispatcher.mission is None
    assert all(new is not old for new in result.actions for old in dispatcher.actions)


# --- state_digest ----------------------------------------------------------------------------------------

# A robot half way along a route, with an action running and a battery at 50.2 %.
BASE = on_order(
    started(route("r", (1.0, 0.0), (2.0, 0.0))).order,
    2,
    extra_actions=[("x", ActionStatus.RUNNING)],
    battery=50.2,
)


@pytest.mark.parametrize(
    "change",
    [
        pytest.param({"order_id": "m1-n1-r0"}, id="order-id"),
        pytest.param({"order_update_id": 1}, id="order-update-id"),
        pytest.param({"last_node_sequence_id": 4, "last_node_id": "m1-n0-r0-s4"}, id="last-node"),
        pytest.param({"node_states": []}, id="node-states"),
        pytest.param({"edge_states": []}, id="edge-states"),
        pytest.param(
            {
                "action_states": [
                    BASE.action_states[0].model_copy(update={"action_status": ActionStatus.FINISHED})
                ]
            },
            id="action-status",
        ),
        pytest.param({"action_states": []}, id="action-gone"),
        pytest.param({"errors": [error("blocked", ErrorLevel.WARNING)]}, id="warning-error"),
        pytest.param(
            {"errors": [error("blocked", ErrorLevel.FATAL, nodeId="m1-n0-r0-s4")]}, id="fatal-error"
        ),
        pytest.param(
            {"battery_state": BASE.battery_state.model_copy(update={"battery_charge": 51.0})}, id="battery"
        ),
        pytest.param(
            {"battery_state": BASE.battery_state.model_copy(update={"charging": True})}, id="charging"
        ),
        pytest.param({"operating_mode": OperatingMode.MANUAL}, id="operating-mode"),
        pytest.param({"paused": True}, id="paused"),
        pytest.param(  # 3.0 reports instant actions apart from the order's
            {
                "instant_action_states": [
                    ActionState(action_id="teleop-1", action_status=ActionStatus.FINISHED)
                ]
            },
            id="3.0-instant-action",
        ),
    ],
)
def test_the_digest_changes_with_what_steps_read(change: dict) -> None:
    assert state_digest(BASE.model_copy(update=change)).full != state_digest(BASE).full


@pytest.mark.parametrize(
    "change",
    [
        pytest.param(
            {"agv_position": BASE.agv_position.model_copy(update={"x": 7.5, "theta": 1.0})}, id="pose"
        ),
        pytest.param({"velocity": robot_state(velocity=(0.5, 0.0, 0.1)).velocity}, id="velocity"),
        pytest.param(
            {"battery_state": BASE.battery_state.model_copy(update={"battery_charge": 50.9})},
            id="battery-fraction",
        ),
        pytest.param({"header_id": 99, "timestamp": "2026-03-01T12:00:05.000Z"}, id="header"),
    ],
)
def test_the_digest_ignores_high_rate_fields(change: dict) -> None:
    assert state_digest(BASE.model_copy(update=change)) == state_digest(BASE)


@pytest.mark.parametrize(
    ("change", "is_event"),
    [
        pytest.param({"order_id": "m1-n1-r0"}, False, id="order-id"),
        pytest.param({"last_node_sequence_id": 4, "last_node_id": "m1-n0-r0-s4"}, False, id="last-node"),
        pytest.param({"node_states": []}, False, id="node-states"),
        pytest.param(
            {
                "action_states": [
                    BASE.action_states[0].model_copy(update={"action_status": ActionStatus.PAUSED})
                ]
            },
            False,
            id="action-paused",
        ),
        pytest.param(
            {
                "action_states": [
                    BASE.action_states[0].model_copy(update={"action_status": ActionStatus.FAILED})
                ]
            },
            True,
            id="action-failed",
        ),
        pytest.param({"errors": [error("blocked", ErrorLevel.WARNING)]}, True, id="error"),
        pytest.param({"operating_mode": OperatingMode.MANUAL}, True, id="operating-mode"),
        pytest.param({"paused": True}, True, id="paused"),
        pytest.param(
            {"battery_state": BASE.battery_state.model_copy(update={"charging": True})}, True, id="charging"
        ),
    ],
)
def test_events_are_what_needs_a_step_whatever_order_the_robot_holds(change: dict, is_event: bool) -> None:
    changed, base = state_digest(BASE.model_copy(update=change)), state_digest(BASE)
    assert (changed.events != base.events or changed.finished_actions != base.finished_actions) is is_event


def test_a_robot_with_nodes_edges_or_actions_left_is_busy() -> None:
    assert state_digest(BASE).busy
    assert not state_digest(robot_state(order_id="m1-n0-r0", last_node_sequence_id=2)).busy
    waiting_action = robot_state(order_id="m1-n0-r0", action_states=[("a", ActionStatus.WAITING)])
    assert state_digest(waiting_action).busy


# --- takes_order_only: the states the bridge need not wake a step for -------------------------------------

IDLE_AFTER_M0 = robot_state(order_id="m0-n0-r0", last_node_sequence_id=2)
TAKEN_M1 = robot_state(order_id="m1-n0-r0", node_states=[2])


def idle_after_m0(*actions: tuple[str, ActionStatus]) -> State:
    """IDLE_AFTER_M0 with these action states (of the order before, or instant actions)."""
    return robot_state(order_id="m0-n0-r0", last_node_sequence_id=2, action_states=actions)


def taken_m1(*actions: tuple[str, ActionStatus]) -> State:
    """TAKEN_M1 with these action states."""
    return robot_state(order_id="m1-n0-r0", node_states=[2], action_states=actions)


def _takes_order_only(before: State, after: State) -> bool:
    return takes_order_only(state_digest(before), state_digest(after))


@pytest.mark.parametrize(
    ("before", "after"),
    [
        pytest.param(IDLE_AFTER_M0, TAKEN_M1, id="idle-takes-a-new-order"),
        pytest.param(robot_state(), TAKEN_M1, id="fresh-robot-takes-its-first-order"),
        pytest.param(
            TAKEN_M1,
            robot_state(order_id="m1-n0-r0", order_update_id=1, node_states=[2, 4]),
            id="busy-takes-an-update",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            robot_state(order_id="m1-n0-r0", node_states=[2], pose=(3.0, 1.0, 0.5, "map")),
            id="moving-while-taking",
        ),
        pytest.param(
            idle_after_m0(("factsheet-1", ActionStatus.FINISHED), ("pick", ActionStatus.FAILED)),
            TAKEN_M1,
            id="dropping-the-finished-actions-of-before",
        ),
        pytest.param(
            idle_after_m0(("factsheet-1", ActionStatus.FINISHED), ("pick", ActionStatus.FINISHED)),
            taken_m1(("factsheet-1", ActionStatus.FINISHED)),
            id="keeping-some-finished-actions",
        ),
    ],
)
def test_taking_an_order_and_nothing_else_needs_no_step(before: State, after: State) -> None:
    assert _takes_order_only(before, after)


@pytest.mark.parametrize(
    ("before", "after"),
    [
        pytest.param(TAKEN_M1, robot_state(order_id="m1-n0-r0", last_node_sequence_id=2), id="finishing"),
        pytest.param(
            robot_state(order_id="m1-n0-r0", node_states=[2, 4]),
            robot_state(order_id="m1-n0-r0", last_node_sequence_id=2, node_states=[4]),
            id="progress-on-the-same-order",
        ),
        pytest.param(
            TAKEN_M1,
            robot_state(order_id="m2-n0-r0", node_states=[2]),
            id="leaving-an-order-unfinished-for-another",
        ),
        pytest.param(
            robot_state(order_id="m1-n0-r0", order_update_id=1, node_states=[2]),
            robot_state(order_id="m1-n0-r0", order_update_id=0, node_states=[2]),
            id="an-older-update",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            robot_state(order_id="m1-n0-r0", node_states=[2], errors=[error("noRoute", ErrorLevel.WARNING)]),
            id="taking-with-an-error",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            taken_m1(("ia", ActionStatus.FINISHED)),
            id="taking-while-an-instant-action-finishes",
        ),
        pytest.param(
            idle_after_m0(("ia", ActionStatus.FINISHED)),
            taken_m1(("ia", ActionStatus.FAILED)),
            id="taking-while-a-finished-action-turns-failed",
        ),
        pytest.param(
            idle_after_m0(("ia", ActionStatus.FINISHED)),
            taken_m1(("ib", ActionStatus.FINISHED)),
            id="dropping-one-finished-action-while-another-finishes",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            robot_state(order_id="m1-n0-r0", node_states=[2], battery=12.0),
            id="taking-with-a-battery-change",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            taken_m1(("hold", ActionStatus.RUNNING)),
            id="taking-with-its-action-already-running",
        ),
        pytest.param(
            IDLE_AFTER_M0,
            robot_state(order_id="m1-n0-r0", last_node_sequence_id=2),
            id="taking-and-finishing-at-once",
        ),
        pytest.param(
            robot_state(order_id="m1-n0-r0", last_node_sequence_id=2),
            TAKEN_M1,
            id="the-finished-order-again",
        ),
        pytest.param(
            robot_state(order_id="m1-n0-r0", last_node_sequence_id=2),
            robot_state(order_id="m1-n0-r0", order_update_id=1, last_node_sequence_id=2, node_states=[4]),
            id="an-update-of-the-finished-order",
        ),
    ],
)
def test_any_other_change_needs_a_step(before: State, after: State) -> None:
    assert not _takes_order_only(before, after)


def test_a_digest_stored_without_its_finished_actions_apart_cannot_tell_and_needs_a_step() -> None:
    before = replace(state_digest(IDLE_AFTER_M0), finished_actions=NO_FINISHED_ACTIONS)

    assert not takes_order_only(before, state_digest(TAKEN_M1))
