"""Instant actions and what a step reads of the robot's state beside its mission: tracking the instant
actions sent until the robot reports them final, sending the due ones, the legacy-key compatibility rule,
the charging flag, and the cancelOrder of a mission's order. Pure, as the step that calls it."""

from __future__ import annotations

from datetime import datetime

from dispatch.held import FINAL, arrived_after_order
from dispatch.records import ActionRecord, DispatchSettings, MissionRecord, Outgoing, RobotView, StepResult
from dispatch.vocabulary import MissionState, RobotState
from vda5050 import compat, orders
from vda5050 import state as vda_state
from vda5050.codec import ACTIONS_KEY, LEGACY_INSTANT_ACTIONS_KEY
from vda5050.models import ActionStatus, ActionType, Error, State


def track_instant_actions(result: StepResult, state: State | None, state_arrived_at: datetime | None) -> None:
    """The robot's reports of our instant actions. One it reported started, unfinished, that a state holding
    no order (a fresh process) and sent after the action reached it no longer names at all was forgotten:
    the robot restarted, and the action goes out again. (A robot may drop action states when it takes a new
    order: with an order held, a missing state proves nothing.)"""
    if state is None:
        return
    for action in result.actions:
        status = vda_state.action_status(state, action.action_id)
        if (
            status is None
            and action.status is not None
            and not state.order_id
            and action.sent_at is not None
            and arrived_after_order(state_arrived_at, action.sent_at)
        ):
            action.status = None
            action.sent_at = None  # due now (`send_instant_actions`)
            continue
        if status is None and action.action_type == ActionType.CANCEL_ORDER and action.sent_at is not None:
            refusal = compat.cancel_refusal(state, action.action_id)
            if refusal is not None:
                status = ActionStatus.FAILED
                result.rules_applied.append((compat.Rule.CANCEL_REFUSED_BY_ERROR_ONLY, describe([refusal])))
        if status is None or status.value == action.status:
            continue
        action.status = status.value
        if status == ActionStatus.FINISHED and action.action_type == ActionType.START_TELEOP:
            result.robot_state = RobotState.TELEOP
        elif status == ActionStatus.FINISHED and action.action_type == ActionType.STOP_TELEOP:
            result.robot_state = RobotState.ON_TASK if _has_running_mission(result) else RobotState.IDLE


def switch_to_legacy_key(result: StepResult, robot: RobotView, state: State | None) -> None:
    """Compatibility rule LEGACY_INSTANT_ACTIONS_KEY: a robot that rejected our `actions` gets its
    unacknowledged instant actions again at once, under the 1.1 key, unless an operator chose the key."""
    if state is None or robot.instant_actions_key != ACTIONS_KEY or robot.instant_actions_key_by_operator:
        return
    waiting = [a for a in result.actions if a.status is None and a.sent_at is not None]
    rejection = compat.actions_key_rejection(state) if waiting else None
    if rejection is None:
        return
    result.instant_actions_key = LEGACY_INSTANT_ACTIONS_KEY
    result.rules_applied.append((compat.Rule.LEGACY_INSTANT_ACTIONS_KEY, describe([rejection])))
    for action in waiting:
        action.sent_at = None  # due now (`send_instant_actions`)


def track_charging(result: StepResult, state: State | None) -> None:
    if state is None:
        return
    charging = state.battery_state.charging
    if charging and result.robot_state == RobotState.IDLE:
        result.robot_state = RobotState.CHARGING
    elif not charging and result.robot_state == RobotState.CHARGING:
        result.robot_state = RobotState.IDLE


def send_instant_actions(
    result: StepResult, robot: RobotView, state: State | None, now: datetime, settings: DispatchSettings
) -> None:
    """Send new instant actions, re-send unacknowledged ones after a timeout; never on every state, and
    not while the robot is offline or its operating mode leaves the master out of control (in 3.0's
    INTERVENED only cancelOrder goes out)."""
    if not robot.online:
        return
    due = [
        action
        for action in result.actions
        if action.status is None
        and (action.sent_at is None or now - action.sent_at >= settings.instant_action_resend)
        and (state is None or vda_state.may_receive_instant_action(state, action.action_type))
    ]
    if not due:
        return
    for action in due:
        action.sent_at = now
        action.send_count += 1
    content = orders.instant_actions(
        orders.instant_action(a.action_type, a.action_id, a.parameters) for a in due
    )
    result.messages.append(Outgoing(content))


def _has_running_mission(result: StepResult) -> bool:
    return result.mission is not None and result.mission.state == MissionState.RUNNING


def pending_action(result: StepResult, action_type: str) -> ActionRecord | None:
    """An instant action of this type the robot has not yet reported FINISHED or FAILED."""
    for action in result.actions:
        if action.action_type == action_type and action.status not in FINAL:
            return action
    return None


def order_cancel(result: StepResult, mission: MissionRecord) -> ActionRecord | None:
    """The cancelOrder for the mission's current order, if one was requested and is still tracked."""
    assert mission.order is not None
    prefix = f"{mission.order['orderId']}-cancel"
    for action in result.actions:
        if action.action_type == ActionType.CANCEL_ORDER and action.action_id.startswith(prefix):
            return action
    return None


def cancel_of_order(result: StepResult, mission: MissionRecord) -> ActionRecord:
    """The cancelOrder for the mission's current order, requested now if it was not yet."""
    action = order_cancel(result, mission)
    if action is not None:
        return action
    assert mission.order is not None
    action = ActionRecord(
        action_id=orders.new_action_id(f"{mission.order['orderId']}-cancel"),
        action_type=ActionType.CANCEL_ORDER,
        mission=mission.name,
        status=None,
        sent_at=None,
    )
    result.actions.append(action)
    return action


def describe(errors: list[Error]) -> str:
    return "\n".join(error.error_description or error.error_type for error in errors)
