"""Whether a queued mission starts now, and why it waits if not; a mission assignment bound to a robot that
became unfit before it took the mission up goes back to the pool. Pure: part of `dispatch.step`."""

from __future__ import annotations

from datetime import datetime

from dispatch import engine
from dispatch.ending import DEADLINE_PASSED, end
from dispatch.instant import cancel_of_order, describe, pending_action
from dispatch.records import MissionRecord, RobotView, StepResult
from dispatch.stations import CHARGING
from dispatch.vocabulary import (
    DONE_STATES,
    FailureCategory,
    Lifecycle,
    MissionPurpose,
    MissionState,
    NodeKind,
    RobotState,
)
from vda5050 import maps
from vda5050 import state as vda_state
from vda5050.models import ActionType, State


def try_start(
    result: StepResult, robot: RobotView, state: State | None, mission: MissionRecord, now: datetime
) -> None:
    if mission.lifecycle == Lifecycle.PENDING_DELETE:
        result.delete_mission = True
        return
    if mission.needs_canceled:
        end(result, mission, MissionState.CANCELED, now, category=FailureCategory.CANCELED)
        return
    if mission.deadline is not None and now >= mission.deadline:
        end(
            result,
            mission,
            MissionState.FAILED,
            now,
            reason=DEADLINE_PASSED,
            category=FailureCategory.DEADLINE,
        )
        return
    charging_trip = mission.purpose == MissionPurpose.CHARGE
    unfit = why_unfit(robot, state, charging_trip=charging_trip)
    if unfit is not None and mission.assignment:
        result.release = unfit  # bound by assignment: another robot may run it now
        mission.waiting_reason = unfit
        return
    reason = _why_not_start(result, robot, state, charging_trip=charging_trip) or _maps_missing(
        state, mission
    )
    if reason is not None:
        mission.waiting_reason = reason
        return
    mission.waiting_reason = None
    mission.state = MissionState.RUNNING
    mission.start_timestamp = now
    mission.node_status = {
        **mission.node_status,
        engine.ROOT: {"state": MissionState.RUNNING, "error_msg": None},
    }
    result.robot_state = RobotState.ON_TASK


def release_unaccepted(
    result: StepResult, robot: RobotView, state: State | None, mission: MissionRecord
) -> bool:
    """A mission assignment bound to the robot, started but not yet taken up (its first order never
    accepted, no progress, no leaf ended), whose robot became unfit (`why_unfit`) goes back to the pool
    as if it had never started: PENDING, its tree's states new, no order. Its order is canceled on the robot
    (at once if online, else when it comes back: the robot must never run it later); the leaf's attempt
    count stays, so the next robot's order has an orderId of its own whatever the first one holds."""
    unfit = why_unfit(robot, state)
    if unfit is None or not mission.assignment or not _not_taken_up(mission):
        return False
    try:
        tree = engine.apply_route_updates(engine.parse_tree(mission.mission_tree), mission.update_nodes)
    except engine.TreeError:
        return False  # the step fails it (`_advance`)
    if robot.lifecycle != Lifecycle.ALIVE:
        result.delete_robot = True  # as when it ends a running mission (`_ended_by_time_or_owner`)
    elif mission.order is not None:
        cancel_of_order(result, mission)
    mission.state = MissionState.PENDING
    mission.start_timestamp = None
    mission.node_status = engine.initial_node_status(tree)
    mission.current_node = 0
    mission.order = None
    mission.order_sent_at = None
    mission.order_accepted = False
    mission.progress = mission.progress_seen_at = None
    mission.waiting_reason = unfit
    if result.robot_state == RobotState.ON_TASK:
        result.robot_state = RobotState.IDLE
    result.release = unfit
    return True


def _not_taken_up(mission: MissionRecord) -> bool:
    """The robot has done nothing of the running mission yet: at most its first order sent, never
    accepted, no progress seen, no node of the tree ended, and no cancel or end asked for."""
    return (
        not mission.order_accepted
        and mission.progress is None
        and sum(mission.attempts.values()) <= 1
        and not mission.needs_canceled
        and mission.lifecycle == Lifecycle.ALIVE
        and not any(status["state"] in DONE_STATES for status in mission.node_status.values())
    )


def _why_not_start(
    result: StepResult, robot: RobotView, state: State | None, *, charging_trip: bool = False
) -> str | None:
    unfit = why_unfit(robot, state, charging_trip=charging_trip)
    if unfit is not None:
        return unfit
    assert state is not None  # a robot without a state is offline
    if result.robot_state == RobotState.TELEOP:
        return "Robot is in teleop"
    if result.robot_state == RobotState.CHARGING:
        return CHARGING  # until its charger's plan sends stopCharging (`dispatch.stations`)
    if pending_action(result, ActionType.CANCEL_ORDER) is not None:
        return "Waiting for the robot to cancel its previous order"
    if not vda_state.may_receive_orders(state):
        return f"Robot is in {state.operating_mode.value} mode"
    if not vda_state.is_idle(state):
        return "Robot is busy with an earlier order"
    return None


def why_unfit(robot: RobotView, state: State | None, *, charging_trip: bool = False) -> str | None:
    """Why the robot cannot take a mission until something outside the mission changes: it is being
    deleted, offline, below its critical battery level or due to charge (unless the mission is its trip to
    a charger) or reports a FATAL error of its own. A mission assignment bound to it goes back to the pool
    (`StepResult.release`)."""
    if robot.lifecycle != Lifecycle.ALIVE:
        return "Robot is being deleted"
    if not robot.online or state is None:
        return "Robot is offline"
    charge = state.battery_state.battery_charge
    if charge < robot.battery_critical_level and not charging_trip:
        return f"Battery {charge:g}% is below the robot's critical level {robot.battery_critical_level:g}%"
    threshold = robot.charge_threshold
    if threshold is not None and charge <= threshold and not charging_trip:
        return f"Battery {charge:g}% is due to charge (at or below {threshold:g}%): it charges first"
    # A FATAL error about an earlier order ended that order's leaf; one about nothing in particular means
    # the robot itself cannot work until someone fixes it.
    fatal = [error for error in vda_state.fatal_errors(state) if not error.error_references]
    if fatal:
        return f"Robot reports a FATAL error: {describe(fatal)}"
    return None


def _maps_missing(state: State | None, mission: MissionRecord) -> str | None:
    """Why a mission waits for maps: its route waypoints name a map the robot reports no ENABLED version
    of (a robot that reports no maps at all is not held, `vda5050.maps.enabled_map_ids`). A tree that does
    not parse is the step's to fail, not this check's."""
    if state is None or maps.enabled_map_ids(state) is None:
        return None  # no maps reported: nothing to wait for, and no tree to parse
    try:
        tree = engine.apply_route_updates(engine.parse_tree(mission.mission_tree), mission.update_nodes)
    except engine.TreeError:
        return None
    return maps_missing_for(state, [node for node in tree.nodes if node.kind == NodeKind.ROUTE])


def maps_missing_for(state: State, leaves: list[engine.Node]) -> str | None:
    missing = maps.maps_not_enabled(
        state, [map_id for leaf in leaves for map_id in maps.waypoint_map_ids(leaf.params["waypoints"])]
    )
    if not missing:
        return None
    return f"Waiting for map {', '.join(missing)} to be enabled on the robot"
