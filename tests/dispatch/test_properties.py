"""Properties of every step: repeating it changes nothing, inputs are never mutated, and the digest the
bridge wakes steps by covers what steps read (and not the pose)."""

import copy
from collections.abc import Callable
from dataclasses import replace
from datetime import timedelta

import pytest

from missions import dispatch
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
from vda5050.models import ActionStatus, ErrorLevel, OperatingMode, State

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


def _with_actions(*actions: dispatch.ActionRecord, state: State = IDLE_STATE, **robot) -> Scenario:
    return lambda: (Dispatcher(None, robot=robot_view(**robot), actions=list(actions)), state, 0.0)


def _notify_started() -> tuple[Dispatcher, State, float]:
    return Dispatcher(mission(notify("n"), route("r"))), IDLE_STATE, 0.0


TELEOP_FINISHED = instant_action(dispatch.START_TELEOP, "teleop-1", sent_at=NOW)
SCENARIOS: dict[str, Scenario] = {
    "start": _queued(),
    "waiting-for-battery": lambda: (Dispatcher(mission()), robot_state(battery=3.0), 0.0),
    "deadline-before-start": _queued(deadline=NOW),
    "delete-before-start": _queued(lifecycle=dispatch.PENDING_DELETE),
    "resend-due": _on_running([route("r")], lambda d: IDLE_STATE, after=3.0),
    "accepted": _on_running([route("r", (1.0, 0.0), (2.0, 0.0))], lambda d: on_order(d.order, 0)),
    "progress": _on_running(
        [route("r", (1.0, 0.0), (2.0, 0.0), allowedDeviationXY=0.0)], lambda d: on_order(d.order, 2)
    ),
    "route-done-next-order": _on_running([route("r1"), route("r2")], lambda d: finished(d.order)),
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
        [action("p", dispatch.PAUSE_ORDER), route("r")],
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
        instant_action(dispatch.FACTSHEET_REQUEST), instant_action(dispatch.STOP_TELEOP)
    ),
    "instant-action-resend": _with_actions(
        instant_action(dispatch.FACTSHEET_REQUEST, sent_at=NOW - SETTINGS.instant_action_resend)
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

    result = dispatch.step(
        now=dispatcher.now + timedelta(seconds=after),
        robot=dispatcher.robot,
        state=state,
        mission=dispatcher.mission,
        actions=dispatcher.actions,
        settings=SETTINGS,
    )

    assert dispatcher.mission == mission_before
    assert dispatcher.actions == actions_before
    assert state == state_before
    assert result.mission is not dispatcher.mission or dispatcher.mission is None
    assert all(new is not old for new in result.actions for old in dispatcher.actions)


# --- engine_digest ---------------------------------------------------------------------------------------

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
    ],
)
def test_the_digest_changes_with_what_steps_read(change: dict) -> None:
    assert dispatch.engine_digest(BASE.model_copy(update=change)) != dispatch.engine_digest(BASE)


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
    assert dispatch.engine_digest(BASE.model_copy(update=change)) == dispatch.engine_digest(BASE)
