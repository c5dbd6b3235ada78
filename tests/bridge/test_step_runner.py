"""The bridge's step threads (`workers.stepper.StepRunner`, `StepProcess`, `StepProcesses`) against the real
PostgreSQL, Redis and broker."""

import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from django.db import connection, transaction

from missions.choices import MissionState
from missions.models import Mission
from missions.services import StepOutcome, mission_create, robot_step
from robots.models import Robot
from tests.bridge.test_robot_step import put_state
from workers import livestate, metrics, stepper
from workers.stepper import StepProcess, StepProcesses, StepRunner

MakeRobot = Callable[..., Robot]
ROUTE = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}


def _orders_sent() -> int:
    return int(livestate.client().hget(metrics.COUNTERS, f"{metrics.MESSAGES_OUT}|topic=order") or 0)


def test_a_robot_requested_twice_before_its_step_runs_is_stepped_once(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="runner")
    runner = StepRunner(threads=1)

    runner.request([robot.name])
    runner.request([robot.name])

    assert runner.queued() == {robot.name}
    assert runner.run_next(timeout=0) == robot.name
    assert runner.run_next(timeout=0) is None
    assert runner.queued() == set()


def test_a_step_starts_the_robots_mission_and_sends_its_order(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="runner")
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    mission = mission_create(name=None, prefix="runner", spec={"robot": robot.name, "mission_tree": [ROUTE]})
    sent_before = _orders_sent()
    runner = StepRunner(threads=1)

    runner.request([robot.name])
    runner.run_next(timeout=0)

    stored = Mission.objects.get(name=mission.name)
    assert stored.state == MissionState.RUNNING
    assert stored.order is not None and stored.order["nodes"][-1]["nodePosition"]["x"] == 5.0
    assert _orders_sent() == sent_before + 1


@pytest.mark.django_db(transaction=True)
def test_a_request_while_the_robots_step_runs_queues_one_more(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="runner")
    runner = StepRunner(threads=1)
    runner.request([robot.name])

    def step_in_thread() -> None:
        try:
            runner.run_next(timeout=5)
        finally:
            connection.close()

    with transaction.atomic():
        Robot.objects.select_for_update().get(name=robot.name)  # the step waits for this row lock
        worker = threading.Thread(target=step_in_thread)
        worker.start()
        deadline = time.monotonic() + 5
        while runner.queued() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert runner.queued() == set()  # taken off the queue: the step has begun
        runner.request([robot.name])
        assert worker.is_alive()  # still waiting for the lock
    worker.join(timeout=10)

    assert not worker.is_alive()
    assert runner.queued() == {robot.name}


def test_a_failed_step_is_retried_with_backoff_until_it_runs(
    make_robot: MakeRobot, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    robot, mission = _robot_with_mission(make_robot)
    monkeypatch.setattr(stepper, "RETRY_FIRST_SECONDS", 0.2)
    failures_left = [2]

    def step_while_the_database_is_away(*, name: str) -> StepOutcome:
        if failures_left[0]:
            failures_left[0] -= 1
            raise RuntimeError("database went away")
        return robot_step(name=name)

    monkeypatch.setattr(stepper, "robot_step", step_while_the_database_is_away)
    runner = StepRunner(threads=1)
    runner.request([robot.name])

    started = time.monotonic()
    assert runner.run_next(timeout=0) == robot.name
    assert runner.retrying() == {robot.name: 1}
    assert runner.queued() == set()  # not at once: after the backoff
    assert runner.run_next(timeout=5) == robot.name
    assert runner.retrying() == {robot.name: 2}
    assert runner.run_next(timeout=5) == robot.name

    assert time.monotonic() - started >= 0.2 + 0.4  # waited 0.2 s, then twice that
    assert runner.retrying() == {}
    assert Mission.objects.get(name=mission.name).state == MissionState.RUNNING
    assert f"step of robot {robot.name} failed (1 in a row); trying again in 0.2 s" in caplog.text
    assert f"step of robot {robot.name} failed (2 in a row); trying again in 0.4 s" in caplog.text
    assert caplog.text.count("RuntimeError: database went away") == 1  # the traceback once


def test_retry_delays_double_up_to_a_bound() -> None:
    delays = [stepper.retry_delay(failures) for failures in range(1, 10)]

    assert delays[:3] == [
        stepper.RETRY_FIRST_SECONDS,
        2 * stepper.RETRY_FIRST_SECONDS,
        4 * stepper.RETRY_FIRST_SECONDS,
    ]
    assert delays[-1] == stepper.RETRY_MAX_SECONDS
    assert delays == sorted(delays)


def _wait_until_running(mission: str) -> bool:
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        if Mission.objects.get(name=mission).state == MissionState.RUNNING:
            return True
        time.sleep(0.05)
    return False


def _robot_with_mission(make_robot: MakeRobot) -> tuple[Robot, Mission]:
    robot = make_robot(prefix="runner")
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    mission = mission_create(name=None, prefix="runner", spec={"robot": robot.name, "mission_tree": [ROUTE]})
    return robot, mission


@pytest.mark.django_db(transaction=True)
def test_a_step_process_runs_the_requested_steps_in_its_child(make_robot: MakeRobot) -> None:
    robot, mission = _robot_with_mission(make_robot)
    sent_before = _orders_sent()
    steps = StepProcess(threads=2)
    steps.start()
    try:
        assert steps.pid is not None and steps.pid != os.getpid()
        steps.request([robot.name])
        assert _wait_until_running(mission.name)
    finally:
        steps.close()
    assert _orders_sent() == sent_before + 1
    assert steps.pid is None


@pytest.mark.django_db(transaction=True)
def test_a_step_process_whose_child_died_is_started_again_with_a_step_for_every_robot_with_work(
    make_robot: MakeRobot,
) -> None:
    _, mission = _robot_with_mission(make_robot)
    steps = StepProcess(threads=1)
    steps.start()
    try:
        first = steps.pid
        assert first is not None
        os.kill(first, signal.SIGKILL)
        while Path(f"/proc/{first}/stat").read_text().split(") ")[1][0] != "Z":  # dead, not yet reaped
            time.sleep(0.01)
        steps.request([])  # nothing asked: the dead child goes unnoticed
        assert steps.pid == first
        other, _ = _robot_with_mission(make_robot)
        Mission.objects.filter(robot=other.name).delete()

        steps.request([other.name])  # a request for another robot restarts it, with the robot's step too

        assert steps.pid not in (None, first)
        assert _wait_until_running(mission.name)
    finally:
        steps.close()


@pytest.mark.django_db(transaction=True)
def test_a_step_process_ends_when_the_bridge_is_gone(make_robot: MakeRobot) -> None:
    steps = StepProcess(threads=1)
    steps.start()
    pid = steps.pid
    assert pid is not None
    steps.close()  # what the bridge's exit does to the pipe

    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # joined: it exited and was reaped


@pytest.mark.django_db(transaction=True)
def test_step_processes_run_each_robots_steps_in_its_own_child(make_robot: MakeRobot) -> None:
    steps = StepProcesses(2, threads=1)
    robots = [_robot_with_mission(make_robot) for _ in range(8)]
    by_child = {steps.child_of(robot.name) for robot, _ in robots}
    assert len(by_child) == 2, "eight random names all hash to one child"
    steps.start()
    try:
        pids = {child.pid for child in steps.children}
        assert len(pids) == 2 and os.getpid() not in pids

        steps.request([robot.name for robot, _ in robots])

        assert all(_wait_until_running(mission.name) for _, mission in robots)
    finally:
        steps.close()
    assert all(child.pid is None for child in steps.children)


@pytest.mark.django_db(transaction=True)
def test_each_step_process_ends_when_the_bridges_end_of_its_pipe_closes() -> None:
    """The second child is forked while the first one's pipe is open: it must not keep that pipe alive."""
    steps = StepProcesses(2, threads=1)
    steps.start()
    first = steps.children[0]
    try:
        pid = first.pid
        assert pid is not None
        assert first._sender is not None
        first._sender.close()  # as when the bridge is killed: its ends of the pipes close

        deadline = time.monotonic() + 10
        while Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z":  # exited, not yet reaped
            assert time.monotonic() < deadline, "the first child outlived its pipe"
            time.sleep(0.01)
    finally:
        first._sender = None
        steps.close()
