"""How a mission ends, whoever ends it (its tree, a cancel, a timeout, a deadline, its robot's deletion):
pure, shared by starting (`dispatch.start`) and advancing (`dispatch.step`)."""

from __future__ import annotations

from datetime import datetime

from dispatch import engine
from dispatch.records import MissionRecord, StepResult
from dispatch.vocabulary import FailureCategory, Lifecycle, MissionState, RobotState

TIMED_OUT = "Mission timed out"
DEADLINE_PASSED = "Mission deadline passed"


def finish(
    result: StepResult,
    mission: MissionRecord,
    tree: engine.Tree,
    final_state: str,
    now: datetime,
    *,
    reason: str | None = None,
    category: str | None = None,
) -> None:
    """End a running mission from outside the tree (cancel, timeout, deadline, robot deleted)."""
    finished = engine.finish(tree, mission.node_status, state=final_state, error_msg=reason)
    mission.node_status = finished.node_status
    if finished.current_node is not None:
        mission.current_node = finished.current_node
    end(result, mission, final_state, now, reason=reason, category=category)


def end(
    result: StepResult,
    mission: MissionRecord,
    final_state: str,
    now: datetime,
    *,
    reason: str | None = None,
    category: str | None = None,
) -> None:
    was_running = mission.state == MissionState.RUNNING
    mission.state = final_state
    mission.end_timestamp = now
    mission.waiting_reason = None
    mission.order = None
    mission.node_status = {
        **mission.node_status,
        engine.ROOT: {**mission.node_status.get(engine.ROOT, {"error_msg": None}), "state": final_state},
    }
    if reason is not None:
        mission.failure_reason = reason
    if final_state == MissionState.COMPLETED:
        mission.failure_reason = None  # no stale reason from a branch a selector recovered from
    if final_state != MissionState.COMPLETED:
        mission.failure_category = category or mission.failure_category or FailureCategory.ROBOT_APP
    if (
        was_running
        and result.robot_state in (RobotState.ON_TASK, RobotState.TELEOP)
        and not result.switch_teleop
    ):
        # A pause_order's teleop ends with its mission; an API teleop does not.
        result.robot_state = RobotState.IDLE
    if mission.lifecycle == Lifecycle.PENDING_DELETE:
        result.delete_mission = True
