"""Instant actions (sent once, resent only after a timeout, never to an offline robot), teleop, charging."""

from datetime import timedelta

import pytest

from dispatch.stations import CHARGING
from dispatch.vocabulary import MissionState, RobotState
from tests.dispatch.builders import (
    IDLE_STATE,
    NOW,
    SETTINGS,
    checked_step,
    finished,
    instant_action,
    instant_actions_sent,
    mission,
    robot_state,
    robot_view,
    started,
)
from vda5050.models import ActionStatus, ActionType, BlockingType, OperatingMode

RESEND = SETTINGS.instant_action_resend


def test_a_new_instant_action_is_sent_once_and_marked_sent() -> None:
    factsheet = instant_action(ActionType.FACTSHEET_REQUEST)

    result = checked_step(state=IDLE_STATE, mission=None, actions=[factsheet])

    [sent] = instant_actions_sent(result)
    assert (sent.action_type, sent.action_id, sent.blocking_type) == (
        ActionType.FACTSHEET_REQUEST,
        factsheet.action_id,
        BlockingType.NONE,
    )
    [record] = result.actions
    assert (record.sent_at, record.send_count, record.status) == (NOW, 1, None)


def test_new_instant_actions_are_sent_together_in_one_message() -> None:
    actions = [instant_action(ActionType.FACTSHEET_REQUEST), instant_action(ActionType.START_TELEOP)]

    result = checked_step(state=IDLE_STATE, mission=None, actions=actions)

    assert len(result.messages) == 1
    assert [a.action_type for a in instant_actions_sent(result)] == [
        ActionType.FACTSHEET_REQUEST,
        ActionType.START_TELEOP,
    ]


def test_a_new_instant_action_is_sent_even_before_the_robot_reports_a_state() -> None:
    result = checked_step(state=None, mission=None, actions=[instant_action(ActionType.FACTSHEET_REQUEST)])

    assert len(instant_actions_sent(result)) == 1


def test_an_unacknowledged_instant_action_is_not_resent_before_the_resend_period() -> None:
    sent = instant_action(ActionType.START_TELEOP, sent_at=NOW)

    result = checked_step(
        state=IDLE_STATE, mission=None, actions=[sent], now=NOW + RESEND - timedelta(milliseconds=1)
    )

    assert result.messages == []
    assert result.actions == [sent]


def test_an_unacknowledged_instant_action_is_resent_with_the_same_id_after_the_resend_period() -> None:
    sent = instant_action(ActionType.START_TELEOP, sent_at=NOW)

    result = checked_step(state=IDLE_STATE, mission=None, actions=[sent], now=NOW + RESEND)

    assert [a.action_id for a in instant_actions_sent(result)] == [sent.action_id]
    [record] = result.actions
    assert (record.sent_at, record.send_count) == (NOW + RESEND, 2)


def test_only_the_due_instant_actions_are_resent() -> None:
    old = instant_action(ActionType.START_TELEOP, "old", sent_at=NOW - RESEND)
    recent = instant_action(ActionType.FACTSHEET_REQUEST, "recent", sent_at=NOW)

    result = checked_step(state=IDLE_STATE, mission=None, actions=[old, recent])

    assert [a.action_id for a in instant_actions_sent(result)] == ["old"]


@pytest.mark.parametrize("status", [ActionStatus.WAITING, ActionStatus.RUNNING, ActionStatus.PAUSED])
def test_an_instant_action_the_robot_reports_is_not_resent(status: ActionStatus) -> None:
    sent = instant_action(ActionType.START_TELEOP, sent_at=NOW - RESEND)

    result = checked_step(
        state=robot_state(action_states=[(sent.action_id, status)]), mission=None, actions=[sent]
    )

    assert result.messages == []
    assert result.actions[0].status == status.value


@pytest.mark.parametrize("sent_at", [None, NOW - timedelta(hours=1)])
def test_no_instant_action_is_sent_to_an_offline_robot(sent_at) -> None:
    action = instant_action(ActionType.CANCEL_ORDER, sent_at=sent_at)

    result = checked_step(state=IDLE_STATE, mission=None, actions=[action], robot=robot_view(online=False))

    assert result.messages == []
    assert result.actions == [action]


@pytest.mark.parametrize(
    ("action_type", "status", "before", "after"),
    [
        (ActionType.START_TELEOP, ActionStatus.FINISHED, RobotState.IDLE, RobotState.TELEOP),
        (ActionType.START_TELEOP, ActionStatus.FINISHED, RobotState.ON_TASK, RobotState.TELEOP),
        (ActionType.START_TELEOP, ActionStatus.RUNNING, RobotState.IDLE, RobotState.IDLE),
        (ActionType.START_TELEOP, ActionStatus.FAILED, RobotState.IDLE, RobotState.IDLE),
        (ActionType.STOP_TELEOP, ActionStatus.FINISHED, RobotState.TELEOP, RobotState.IDLE),
        (ActionType.STOP_TELEOP, ActionStatus.FAILED, RobotState.TELEOP, RobotState.TELEOP),
        (ActionType.FACTSHEET_REQUEST, ActionStatus.FINISHED, RobotState.IDLE, RobotState.IDLE),
    ],
)
def test_finished_teleop_actions_switch_the_robot_state(
    action_type: str, status: ActionStatus, before: str, after: str
) -> None:
    sent = instant_action(action_type, sent_at=NOW)

    result = checked_step(
        state=robot_state(action_states=[(sent.action_id, status)]),
        mission=None,
        actions=[sent],
        robot=robot_view(state=before),
    )

    assert result.robot_state == after
    assert result.actions[0].status == status.value
    assert result.messages == []


def test_stop_teleop_returns_to_on_task_while_a_mission_runs() -> None:
    dispatcher = started()
    dispatcher.robot = robot_view(state=RobotState.TELEOP)
    dispatcher.actions = [instant_action(ActionType.STOP_TELEOP, sent_at=dispatcher.now)]

    result = dispatcher.step(
        robot_state(action_states=[(dispatcher.actions[0].action_id, ActionStatus.FINISHED)]), after=1.0
    )

    assert result.robot_state == RobotState.ON_TASK
    assert dispatcher.actions == []  # final: the caller stops tracking it


def test_a_robot_entering_teleop_holds_a_queued_mission_back() -> None:
    sent = instant_action(ActionType.START_TELEOP, sent_at=NOW)

    result = checked_step(
        state=robot_state(action_states=[(sent.action_id, ActionStatus.FINISHED)]),
        mission=mission(),
        actions=[sent],
    )

    assert (result.robot_state, result.mission.state) == (RobotState.TELEOP, MissionState.PENDING)
    assert result.mission.waiting_reason == "Robot is in teleop"


@pytest.mark.parametrize(
    ("before", "charging", "after"),
    [
        (RobotState.IDLE, True, RobotState.CHARGING),
        (RobotState.CHARGING, True, RobotState.CHARGING),
        (RobotState.CHARGING, False, RobotState.IDLE),
        (RobotState.IDLE, False, RobotState.IDLE),
        (RobotState.ON_TASK, True, RobotState.ON_TASK),
        (RobotState.TELEOP, True, RobotState.TELEOP),
    ],
)
def test_charging_follows_the_battery_state_of_a_robot_without_work(
    before: str, charging: bool, after: str
) -> None:
    result = checked_step(state=robot_state(charging=charging), mission=None, robot=robot_view(state=before))

    assert result.robot_state == after


def test_charging_state_is_kept_when_no_state_is_known() -> None:
    result = checked_step(state=None, mission=None, robot=robot_view(state=RobotState.CHARGING))

    assert result.robot_state == RobotState.CHARGING


def test_a_charging_robot_takes_no_mission_until_it_stops_charging() -> None:
    waiting = checked_step(
        state=robot_state(charging=True), mission=mission(), robot=robot_view(state=RobotState.IDLE)
    )

    assert (waiting.robot_state, waiting.mission.state) == (RobotState.CHARGING, MissionState.PENDING)
    assert waiting.mission.waiting_reason == CHARGING

    stopped = checked_step(
        state=robot_state(charging=False), mission=mission(), robot=robot_view(state=RobotState.CHARGING)
    )
    assert (stopped.robot_state, stopped.mission.state) == (RobotState.ON_TASK, MissionState.RUNNING)


def test_a_mission_that_ends_with_its_robot_charging_leaves_it_charging() -> None:
    dispatcher = started(state=robot_state(charging=False))
    assert dispatcher.results[0].robot_state == RobotState.ON_TASK

    done = dispatcher.step(finished(dispatcher.order, charging=True), after=1.0)

    assert (dispatcher.mission.state, done.robot_state) == (MissionState.COMPLETED, RobotState.CHARGING)


@pytest.mark.parametrize("mode", [OperatingMode.MANUAL, OperatingMode.SERVICE, OperatingMode.TEACHIN])
def test_no_instant_action_is_sent_while_the_master_is_not_in_control(mode: OperatingMode) -> None:
    result = checked_step(
        state=robot_state(operating_mode=mode),
        mission=None,
        actions=[instant_action(ActionType.FACTSHEET_REQUEST)],
    )

    assert result.messages == []
