"""Requested steps (`workers.steps`): to a listening bridge over Redis, else to a Celery worker; against the
real Redis, PostgreSQL and a real bridge step process."""

import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import orjson
import pytest
from django.conf import settings

from missions.choices import MissionState
from missions.models import Mission
from missions.services import mission_create
from robots.models import Robot
from tests.bridge.test_robot_step import put_state
from tests.private_redis import PrivateRedis, live_state_in
from tests.waiting import wait_for
from workers import livestate, steps
from workers.stepper import StepProcess

ROUTE = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}


@pytest.fixture
def names() -> Iterator[list[str]]:
    """Two robot names of this test; their markers and requests are dropped after it, and nobody listens."""
    made = [f"requested-{uuid.uuid4().hex[:10]}" for _ in range(2)]
    redis = livestate.client()
    redis.delete(steps.LISTENING)
    yield made
    redis.delete(steps.LISTENING, *(steps.step_marker_key(name) for name in made))
    for entry in redis.lrange(steps.REQUESTED, 0, -1):
        if entry.decode().rsplit(" ", 1)[0] in made:
            redis.lrem(steps.REQUESTED, 0, entry)
    for message in redis.lrange(settings.STEP_QUEUE, 0, -1):
        if any(name in _argsrepr(message) for name in made):
            redis.lrem(settings.STEP_QUEUE, 0, message)


def _argsrepr(message: bytes) -> str:
    return str(orjson.loads(message)["headers"]["argsrepr"])


def celery_steps(name: str) -> int:
    """Celery step tasks queued for the robot (no worker runs during these tests)."""
    messages = livestate.client().lrange(settings.STEP_QUEUE, 0, -1)
    return sum(f"'{name}'" in _argsrepr(message) for message in messages)


def bridge_requests(name: str) -> list[float]:
    """The `at` of each step of the robot waiting for a bridge."""
    entries = (entry.decode().rsplit(" ", 1) for entry in livestate.client().lrange(steps.REQUESTED, 0, -1))
    return [float(at) for robot, at in entries if robot == name]


def listen() -> None:
    livestate.client().set(steps.LISTENING, 1, ex=steps.LISTENING_SECONDS)


def test_while_a_bridge_listens_steps_are_requested_from_it(names: list[str]) -> None:
    listen()

    steps.request_steps(names, at=1234.5)

    assert [bridge_requests(name) for name in names] == [[1234.5], [1234.5]]
    assert [celery_steps(name) for name in names] == [0, 0]


def test_while_no_bridge_listens_steps_go_to_celery_workers(names: list[str]) -> None:
    steps.request_steps(names)

    assert [celery_steps(name) for name in names] == [1, 1]
    assert [bridge_requests(name) for name in names] == [[], []]


def test_a_step_request_made_while_redis_is_away_is_queued_once_it_is_back(
    names: list[str], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    private = PrivateRedis(tmp_path)
    with live_state_in(private.url):
        steps.request_steps_or_later(names[:1])  # nothing listens on the port yet: no error either
        assert "not queued" in caplog.text

        private.start()
        try:
            wait_for(lambda: private.client().exists(steps.step_marker_key(names[0])), timeout=10)
        finally:
            private.kill()

    assert celery_steps(names[0]) == 1  # the broker was up all along


def test_a_robot_whose_step_is_queued_is_not_queued_again_until_its_step_is_taken(names: list[str]) -> None:
    listen()
    steps.request_steps(names[:1], at=1.0)
    steps.request_steps(names[:1], at=2.0)
    assert bridge_requests(names[0]) == [1.0]

    taken = steps.take_requested()
    steps.request_steps(names[:1], at=3.0)

    assert (names[0], 1.0) in taken
    assert bridge_requests(names[0]) == [3.0]


def test_taking_requested_steps_says_the_bridge_listens_and_waits_at_most_the_timeout(
    names: list[str],
) -> None:
    livestate.client().delete(steps.REQUESTED)
    started = time.monotonic()

    assert steps.take_requested(timeout=1) == []

    assert 0.9 <= time.monotonic() - started < 5
    assert 0 < livestate.client().ttl(steps.LISTENING) <= steps.LISTENING_SECONDS


@pytest.mark.django_db(transaction=True)
def test_a_bridge_step_process_starts_a_new_mission_of_an_idle_robot_without_celery(
    make_robot: Callable[..., Robot], names: list[str]
) -> None:
    robot = make_robot(prefix="requested")
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    livestate.client().delete(steps.step_marker_key(robot.name))  # the creation's step, run by a worker
    celery_before = celery_steps(robot.name)
    process = StepProcess(threads=1)
    process.start()
    try:
        deadline = time.monotonic() + 10
        while not livestate.client().exists(steps.LISTENING) and time.monotonic() < deadline:
            time.sleep(0.05)

        mission = mission_create(
            name=None, prefix="requested", spec={"robot": robot.name, "mission_tree": [ROUTE]}
        )

        deadline = time.monotonic() + 10
        while Mission.objects.get(name=mission.name).state != MissionState.RUNNING:
            assert time.monotonic() < deadline, "the bridge's step process did not start the mission"
            time.sleep(0.05)
    finally:
        process.close()
    assert celery_steps(robot.name) == celery_before
