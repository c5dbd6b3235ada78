"""Robot-side faults, judged in the pure core: a robot that no longer holds the order its mission sent (it
restarted: a fresh process holds no order, or an old one), and one that holds it but does not execute it (a
stack that takes an order or an order update and then stands still). The step (`dispatch.step`) acts on
them: the rest of a route goes out as a new order from where the robot stands, a running action fails.

No false alarms (README, "Routes without stops"): a robot's state that may have left it before the order
reached it says nothing (`dispatch.held.arrived_after_order`); a robot that is slow, paused, in teleop,
driving, at a running action or reporting an error is never stalled, and any change of its progress on the
order restarts the clock.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from dispatch.held import STARTED, arrived_after_order
from dispatch.records import MissionRecord, RobotView
from dispatch.sent import SentOrder
from dispatch.vocabulary import RobotState
from vda5050 import orders
from vda5050 import state as vda_state
from vda5050.models import OrderContent, State

ENDED = "ended"  # in `MissionRecord.progress`: when the order was canceled as stalled (ISO 8601)


def lost_reason(order_id: str) -> str:
    return (
        f"Robot no longer holds order {order_id} (it may have restarted); the action may or may not have run"
    )


def stalled_reason(order_id: str, update_id: int, seconds: float) -> str:
    return (
        f"Robot took order {order_id} (update {update_id}) but showed no progress on it for {seconds:g} s; "
        "it was canceled"
    )


def unconfirmed_reason(order_id: str, update_id: int, seconds: float) -> str:
    return (
        f"Robot took order {order_id} (update {update_id}) but showed no progress on it for {seconds:g} s, "
        f"nor confirmed its cancel for {seconds:g} s more"
    )


def progress_mark(state: State) -> dict[str, Any]:
    """What the robot shows of its progress on the order it holds: the order (update), the last node it
    reached and the status of every action it reports."""
    return {
        "orderId": state.order_id,
        "orderUpdateId": state.order_update_id,
        "lastNodeSequenceId": state.last_node_sequence_id,
        "actions": ",".join(
            f"{a.action_id}={a.action_status.value}" for a in vda_state.all_action_states(state)
        ),
    }


def order_lost(
    robot: RobotView, state: State, state_arrived_at: datetime | None, mission: MissionRecord, sent: SentOrder
) -> bool:
    """The robot held the mission's order (a state showed it) and its latest state, one that would hold the
    order still (`arrived_after_order`), names no order or another one. A robot that may not take orders
    now (teleop, manual modes) is left alone until it may: what it holds then decides."""
    if mission.order_sent_at is not None and not arrived_after_order(state_arrived_at, mission.order_sent_at):
        return False
    return (
        robot.online
        and robot.state != RobotState.TELEOP
        and vda_state.may_receive_orders(state)
        and _held(mission, sent)
        and state.order_id != sent.stored.order_id
    )


def order_ended(mission: MissionRecord, sent: SentOrder) -> bool:
    """The order was canceled as stalled (`watch_progress`): the rest of its leaf waits for the cancel, then
    goes out anew."""
    progress = mission.progress
    return progress is not None and progress.get(ENDED, False) and progress["orderId"] == sent.stored.order_id


def _held(mission: MissionRecord, sent: SentOrder) -> bool:
    progress = mission.progress
    return mission.order_accepted or (progress is not None and progress["orderId"] == sent.stored.order_id)


def watch_progress(
    robot: RobotView, state: State, mission: MissionRecord, now: datetime, stall_seconds: float
) -> bool:
    """Record the robot's progress on the order it holds (the running leaf's); True once it has shown none
    for `stall_seconds` while nothing excused it (`_excused`): the order is stalled.

    A change of progress, or a state that excuses standing still, restarts the clock; beat wakes a step of a
    robot whose clock has run that long (`missions.selectors.robots_stalled`), as a stalled robot's states
    wake none."""
    mark = progress_mark(state)
    if mark != mission.progress:
        mission.progress = mark
        mission.progress_seen_at = now
        return False
    if not stall_seconds:
        return False
    if mission.progress_seen_at is None or _excused(robot, state):
        mission.progress_seen_at = now
        return False
    return (now - mission.progress_seen_at).total_seconds() >= stall_seconds


def end_stalled(mission: MissionRecord, now: datetime) -> None:
    """Mark the order canceled as stalled (`order_ended`), now; the stall clock starts again, so that beat
    wakes a step once the cancel is overdue (`cancel_overdue`) if no state of the robot did."""
    assert mission.progress is not None
    mission.progress = {**mission.progress, ENDED: now.isoformat()}
    mission.progress_seen_at = now


def cancel_overdue(mission: MissionRecord, now: datetime, stall_seconds: float) -> bool:
    """The robot has not confirmed the cancel of its stalled order for another `stall_seconds` since it was
    sent (and re-sent): its leaf fails rather than wait for the mission's timeout."""
    assert mission.progress is not None
    ended = mission.progress[ENDED]
    if not isinstance(ended, str):  # marked before the time was kept (`true`): counts from now on
        mission.progress = {**mission.progress, ENDED: now.isoformat()}
        return False
    return (now - datetime.fromisoformat(ended)).total_seconds() >= stall_seconds


def _excused(robot: RobotView, state: State) -> bool:
    """Standing still is no stall: the robot is offline, paused, in teleop or a manual mode, driving, at its
    decision point with only horizon ahead (waiting for a zone, `dispatch.zones`), at a running action, or
    reporting an error (which the step and the operator judge)."""
    return (
        not robot.online
        or robot.state == RobotState.TELEOP
        or not vda_state.may_receive_orders(state)
        or bool(state.paused)
        or state.driving
        or vda_state.waits_at_decision_point(state)
        or bool(state.errors)
        or any(a.action_status in STARTED for a in vda_state.all_action_states(state))
    )


def remaining_waypoints(message: OrderContent, progress: dict[str, Any] | None) -> list[orders.Waypoint]:
    """The waypoints of the route `message` carries that the robot had not reached, as far as its progress
    on that order was seen (`progress_mark`)."""
    reached = -1
    if progress is not None and progress["orderId"] == message.order_id:
        reached = progress["lastNodeSequenceId"]
    return [
        orders.Waypoint(
            x=position.x,
            y=position.y,
            theta=position.theta or 0.0,
            map_id=position.map_id,
            allowed_deviation_xy=position.allowed_deviation_xy or 0.0,
            allowed_deviation_theta=position.allowed_deviation_theta or 0.0,
        )
        for node in message.nodes[1:]
        if node.sequence_id > reached and (position := node.node_position) is not None
    ]
