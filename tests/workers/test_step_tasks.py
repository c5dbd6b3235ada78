"""The Celery step task (`workers.tasks.step_robots`) run in this process, against the real PostgreSQL, Redis
and broker."""

import time
from collections.abc import Callable

import pytest

from missions.choices import MissionState
from missions.models import Mission
from missions.robot_step import StepOutcome, robot_step
from missions.services import mission_create
from robots import livestate
from robots.models import Robot
from tests.factories import TEST_ACTOR
from tests.missions.test_robot_step import put_state
from tests.workers.bridge.messages import steps_queued
from workers import long_lived, metrics, step_runs, tuning
from workers.step_requests import queue_steps
from workers.tasks import step_robots

MakeRobot = Callable[..., Robot]
ROUTE = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}


def _orders_sent() -> int:
    return int(livestate.client().hget(metrics.COUNTERS, f"{metrics.MESSAGES_OUT}|topic=order") or 0)


def _robot_with_mission(make_robot: MakeRobot) -> tuple[Robot, Mission]:
    robot = make_robot(prefix="task")
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    mission = mission_create(
        actor=TEST_ACTOR, name=None, prefix="task", spec={"robot": robot.name, "mission_tree": [ROUTE]}
    )
    return robot, mission


def test_a_step_task_starts_each_robots_mission_and_sends_its_order(make_robot: MakeRobot) -> None:
    robots = [_robot_with_mission(make_robot) for _ in range(3)]
    sent_before = _orders_sent()

    step_robots.apply(([robot.name for robot, _ in robots],))

    assert [Mission.objects.get(name=m.name).state for _, m in robots] == [MissionState.RUNNING] * 3
    assert _orders_sent() == sent_before + 3


def test_a_step_clears_its_robots_marker_so_that_a_later_change_queues_another(make_robot: MakeRobot) -> None:
    robot, _ = _robot_with_mission(make_robot)
    queue_steps([robot.name])
    assert steps_queued([robot]) == {robot.name}

    step_robots.apply(([robot.name],))

    assert steps_queued([robot]) == set()


def test_robots_whose_step_failed_are_retried_alone_until_their_steps_run(
    make_robot: MakeRobot, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    (healthy, healthy_mission), (failing, failing_mission) = (
        _robot_with_mission(make_robot) for _ in range(2)
    )
    failures_left = [2]
    stepped = []

    def step_while_the_database_is_away(*, name: str) -> StepOutcome:
        stepped.append(name)
        if name == failing.name and failures_left[0]:
            failures_left[0] -= 1
            raise RuntimeError("database went away")
        return robot_step(name=name)

    monkeypatch.setattr(step_runs, "robot_step", step_while_the_database_is_away)

    step_robots.apply(([failing.name, healthy.name],))  # eager: a retry runs at once, without its countdown

    assert stepped == [failing.name, healthy.name, failing.name, failing.name]
    states = [Mission.objects.get(name=m.name).state for m in (healthy_mission, failing_mission)]
    assert states == [MissionState.RUNNING, MissionState.RUNNING]
    assert "steps of 1 robots failed; trying them again in 0.5 s" in caplog.text
    assert "steps of 1 robots failed; trying them again in 1.0 s" in caplog.text
    assert caplog.text.count("RuntimeError: database went away") == 1  # the traceback once


def test_retry_delays_double_up_to_a_bound() -> None:
    delays = [long_lived.retry_delay(failures) for failures in range(1, 10)]

    assert delays[:3] == [
        tuning.RETRY_FIRST_SECONDS,
        2 * tuning.RETRY_FIRST_SECONDS,
        4 * tuning.RETRY_FIRST_SECONDS,
    ]
    assert delays[-1] == tuning.RETRY_MAX_SECONDS
    assert delays == sorted(delays)


def test_start_up_work_is_tried_again_with_backoff_until_it_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """What the bridge and the step workers do once at start (load the robots, step every robot with work)
    waits for PostgreSQL and Redis instead of ending the process."""
    monkeypatch.setattr(tuning, "RETRY_FIRST_SECONDS", 0.01)
    tries = []

    def load_while_the_database_is_away() -> None:
        tries.append(time.monotonic())
        if len(tries) < 3:
            raise RuntimeError("database went away")

    long_lived.keep_trying("loading the robots", load_while_the_database_is_away)

    assert len(tries) == 3
    assert tries[1] - tries[0] >= 0.01 and tries[2] - tries[1] >= 0.02  # waited, then twice as long
