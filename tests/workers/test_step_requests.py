"""Requested steps (`workers.step_requests`): Celery tasks on the steps queue, at most one queued per robot;
against the real Redis (the Celery broker)."""

import time
import uuid
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import orjson
import pytest
import redis
from celery import current_app as app
from django.conf import settings
from kombu.transport.redis import PRIORITY_STEPS

from robots import livestate
from tests.factories import TEST_ACTOR, ZoneSetFactory
from tests.private_redis import PrivateRedis, live_state_in
from tests.waiting import wait_for
from workers import step_requests, tuning
from workers.step_requests import StepPriority
from workers.tasks import plan_zones_while_enabled
from zones.services import zone_set_enable


@pytest.fixture
def names() -> Iterator[list[str]]:
    """Robot names of this test; their markers and queued tasks are dropped after it."""
    made = [f"requested-{uuid.uuid4().hex[:10]}" for _ in range(20)]
    yield made
    redis = livestate.client()
    redis.delete(*(livestate.step_marker_key(name) for name in made))
    for key in step_requests.step_queue_keys():
        for message in redis.lrange(key, 0, -1):
            if set(_robots_of(message)) & set(made):
                redis.lrem(key, 0, message)


def _robots_of(message: bytes) -> list[str]:
    body = orjson.loads(message)
    if body["headers"]["task"] != "fleet.step_robots":
        return []
    return orjson.loads(__import__("base64").b64decode(body["body"]))[0][0]


def step_tasks(names: list[str], priority: StepPriority = StepPriority.ROUTINE) -> list[list[str]]:
    """The step tasks queued at `priority` that carry any of `names`: the robots of each, oldest first."""
    queued = [
        _robots_of(message) for message in reversed(livestate.client().lrange(_list_of(priority), 0, -1))
    ]
    return [robots for robots in queued if set(robots) & set(names)]


def _list_of(priority: StepPriority) -> str:
    return step_requests.step_queue_keys()[PRIORITY_STEPS.index(priority)]


def test_steps_go_to_the_steps_queue_a_task_per_so_many_robots(names: list[str]) -> None:
    step_requests.queue_steps(names, at=1234.5)

    size = settings.STEP_TASK_ROBOTS
    assert step_tasks(names) == [names[start : start + size] for start in range(0, len(names), size)]


def test_a_step_task_shows_celerys_tools_its_robots(names: list[str]) -> None:
    step_requests.queue_steps(names[:2], at=1234.5)

    queued = livestate.client().lrange(_list_of(StepPriority.ROUTINE), 0, -1)
    (message,) = [message for message in queued if _robots_of(message) == names[:2]]
    headers = orjson.loads(message)["headers"]
    assert (headers["argsrepr"], headers["kwargsrepr"]) == (repr((names[:2], 1234.5)), "{}")


def test_a_robot_whose_step_is_queued_is_not_queued_again_until_its_step_reads_its_state(
    names: list[str],
) -> None:
    step_requests.queue_steps(names[:1])
    step_requests.queue_steps(names[:2])
    assert step_tasks(names) == [names[:1], names[1:2]]

    livestate.state_for_step(names[0])  # what its step reads first
    step_requests.queue_steps(names[:2])

    assert step_tasks(names) == [names[:1], names[1:2], names[:1]]


def test_requests_made_while_the_sender_is_busy_go_out_together_in_tasks_of_several_robots(
    names: list[str],
) -> None:
    sender = step_requests._StepSender()
    with sender._changed:  # held, as while the sender sends: it cannot take the requests meanwhile
        for name in names[:10]:
            sender.add([name], at=time.time())

    assert sender.wait_until_queued(timeout=10)
    assert step_tasks(names, StepPriority.ASKED) == [names[:8], names[8:10]]


def test_a_step_a_service_asked_for_is_delivered_before_routine_ones_queued_earlier(names: list[str]) -> None:
    _no_step_tasks_waiting()
    step_requests.queue_steps(names[:1])  # a robot's state: routine
    step_requests.queue_steps_soon(names[1:2])  # an API call, say a mission's start
    assert step_requests.wait_until_queued(timeout=10)

    delivered = []
    with app.connection_for_read() as connection:  # as a worker's consumer takes them: kombu, the real broker
        channel = connection.default_channel
        while (message := channel.basic_get(settings.STEP_QUEUE, no_ack=True)) is not None:
            assert message.headers["task"] == step_requests.STEP_TASK
            delivered.append(message.decode()[0][0])
    assert delivered == [names[1:2], names[:1]]


def _no_step_tasks_waiting() -> None:
    """Drop the step tasks earlier tests left (no worker takes them here)."""
    livestate.client().delete(*step_requests.step_queue_keys())


# --- the bridge's held requests (`HeldSteps`) -------------------------------------------------------------


@pytest.fixture
def backlog(names: list[str]) -> Iterator[list[str]]:
    """A routine step task waiting in the broker, as while every worker thread is busy (no worker takes it
    here); the robots of the test apart from its one."""
    step_requests.queue_steps(names[-1:])
    yield names[:-1]


def test_requests_go_out_at_once_while_no_step_task_waits(names: list[str]) -> None:
    _no_step_tasks_waiting()
    held = step_requests.HeldSteps()
    held.request(names[:1], at=1.0)
    held.request(names[1:3], at=2.0)

    assert step_tasks(names) == [names[:1], names[1:3]]
    assert held.wait_seconds(5.0) == 5.0


def test_while_step_tasks_wait_requests_are_held_and_go_out_together_after_the_hold(
    backlog: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "STEP_HOLD_SECONDS", 0.3)
    held = step_requests.HeldSteps()
    held.request(backlog[:1], at=1.0)  # the first reads the backlog
    began = time.monotonic()
    held.request(backlog[1:3], at=3.0)
    held.request(backlog[3:4], at=2.0)

    assert step_tasks(backlog) == [backlog[:1]]  # held: neither a task nor a marker
    assert not livestate.client().exists(livestate.step_marker_key(backlog[1]))
    assert 0.0 < held.wait_seconds(5.0) <= 0.3
    held.send_if_due()
    assert step_tasks(backlog) == [backlog[:1]]

    time.sleep(max(0.0, began + 0.3 - time.monotonic()))
    assert held.wait_seconds(5.0) == 0.0
    held.send_if_due()
    assert step_tasks(backlog) == [backlog[:1], backlog[1:4]]
    (message,) = [
        m
        for m in livestate.client().lrange(_list_of(StepPriority.ROUTINE), 0, -1)
        if _robots_of(m) == backlog[1:4]
    ]
    assert orjson.loads(message)["headers"]["argsrepr"] == repr((backlog[1:4], 2.0))  # the earliest cause
    assert held.wait_seconds(5.0) == 5.0


def test_while_asked_for_step_tasks_wait_the_sender_holds_its_requests_until_the_hold_ends(
    names: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "STEP_HOLD_SECONDS", 0.3)
    _no_step_tasks_waiting()
    step_requests.queue_steps(names[-1:], priority=StepPriority.ASKED)  # waits: no worker takes it here
    sender = step_requests._StepSender()
    sender.add(names[:1], at=time.time())
    assert sender.wait_until_queued(timeout=10)  # sent at once: the sender had not seen the backlog yet

    began = time.monotonic()
    sender.add(names[1:2], at=time.time())
    sender.add(names[2:3], at=time.time())
    time.sleep(0.1)
    assert step_tasks(names, StepPriority.ASKED) == [names[-1:], names[:1]]  # held

    assert sender.wait_until_queued(timeout=10)  # the hold counts as not queued yet
    assert time.monotonic() - began >= 0.3
    assert step_tasks(names, StepPriority.ASKED) == [names[-1:], names[:1], names[1:3]]


def test_routine_step_tasks_waiting_hold_no_asked_for_request(
    names: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "STEP_HOLD_SECONDS", 5.0)
    _no_step_tasks_waiting()
    step_requests.queue_steps(names[-1:])  # routine: an asked-for task would not wait behind it
    sender = step_requests._StepSender()
    for name in names[:2]:
        sender.add([name], at=time.time())
        assert sender.wait_until_queued(timeout=2)

    assert step_tasks(names, StepPriority.ASKED) == [names[:1], names[1:2]]


def test_held_requests_that_fill_a_task_go_out_at_once(backlog: list[str]) -> None:
    size = settings.STEP_TASK_ROBOTS
    held = step_requests.HeldSteps()
    held.request(backlog[:1], at=1.0)
    held.request(backlog[1:size], at=1.0)
    assert step_tasks(backlog) == [backlog[:1]]

    held.request(backlog[size : size + 1], at=1.0)

    assert step_tasks(backlog) == [backlog[:1], backlog[1 : size + 1]]


def test_held_requests_that_cannot_be_queued_stay_held_and_go_out_with_the_next(
    names: list[str], tmp_path: Path
) -> None:
    private = PrivateRedis(tmp_path)
    held = step_requests.HeldSteps()
    with live_state_in(private.url), pytest.raises(redis.ConnectionError):  # the live state's Redis away
        held.request(names[:2], at=1.0)
    assert held.wait_seconds(5.0) == 0.0  # due: the next loop of the bridge tries again at once

    held.request(names[2:3], at=2.0)

    assert step_tasks(names) == [names[:3]]


def test_a_step_request_made_while_redis_is_away_is_queued_once_it_is_back(
    names: list[str], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    private = PrivateRedis(tmp_path)
    with live_state_in(private.url):
        step_requests.queue_steps_soon(names[:1])  # nothing listens on the port yet: no error either
        wait_for(lambda: "not queued" in caplog.text, timeout=10)

        private.start()
        try:
            wait_for(lambda: private.client().exists(livestate.step_marker_key(names[0])), timeout=10)
            assert step_requests.wait_until_queued(timeout=10)  # its task is sent after its marker
        finally:
            private.kill()

    assert step_tasks(names, StepPriority.ASKED) == [names[:1]]  # the broker was up all along


def _tasks(task: str) -> list[bytes]:
    return [
        message
        for message in livestate.client().lrange(settings.STEP_QUEUE, 0, -1)
        if orjson.loads(message)["headers"]["task"] == task
    ]


def _assignment_tasks() -> list[bytes]:
    return _tasks(step_requests.ASSIGN_TASK)


@pytest.fixture
def no_assignment_queued() -> Iterator[None]:
    def clear() -> None:
        redis = livestate.client()
        redis.delete(
            step_requests.ASSIGNMENT_MARKER_KEY,
            step_requests.ASSIGNMENT_RAN_KEY,
            step_requests.ASSIGNMENT_FLEET_BUSY_KEY,
        )
        for message in _assignment_tasks():
            redis.lrem(settings.STEP_QUEUE, 0, message)

    clear()
    yield
    clear()


def test_assignment_runs_are_coalesced_one_queued_at_a_time(no_assignment_queued: None) -> None:
    step_requests.queue_assignment()
    step_requests.queue_assignment()
    assert len(_assignment_tasks()) == 1

    step_requests.assignment_run_started()  # what the run does first
    step_requests.queue_assignment()
    assert len(_assignment_tasks()) == 2


def _eta(message: bytes) -> datetime | None:
    eta = orjson.loads(message)["headers"]["eta"]
    return None if eta is None else datetime.fromisoformat(eta)


def test_a_run_asked_for_right_after_one_started_waits_for_the_run_interval(
    no_assignment_queued: None,
) -> None:
    step_requests.queue_assignment()
    assert _eta(_assignment_tasks()[0]) is None  # no run started lately: at once

    step_requests.assignment_run_started()
    asked_at = datetime.now(UTC)
    step_requests.queue_assignment()
    sent_by = datetime.now(UTC)
    eta = _eta(_assignment_tasks()[0])  # the newest: Celery pushes on the list's left
    assert eta is not None
    interval = timedelta(seconds=step_requests.tuning.ASSIGNMENT_RUN_INTERVAL_SECONDS)
    assert asked_at < eta <= sent_by + interval


def test_a_held_burst_is_run_again_after_its_hold(no_assignment_queued: None) -> None:
    asked_at = datetime.now(UTC)
    step_requests.queue_assignment(countdown=2.0)
    eta = _eta(_assignment_tasks()[0])
    assert eta is not None and asked_at + timedelta(seconds=1.9) < eta < asked_at + timedelta(seconds=3)
    ttl = livestate.client().ttl(step_requests.ASSIGNMENT_MARKER_KEY)
    assert ttl > step_requests.tuning.ASSIGNMENT_MARKER_SECONDS  # the marker outlives the wait


def test_a_lost_assignment_run_blocks_later_ones_only_until_its_marker_expires(
    no_assignment_queued: None,
) -> None:
    step_requests.queue_assignment()
    ttl = livestate.client().ttl(step_requests.ASSIGNMENT_MARKER_KEY)
    assert 0 < ttl <= step_requests.tuning.ASSIGNMENT_MARKER_SECONDS


def test_assignment_asked_soon_is_queued_by_the_sender_thread(no_assignment_queued: None) -> None:
    step_requests.queue_assignment_soon()

    assert step_requests.wait_until_queued(5.0)
    assert len(_assignment_tasks()) == 1


def test_a_new_mission_in_a_busy_fleet_asks_for_its_run_once_the_news_is_old(
    no_assignment_queued: None,
) -> None:
    step_requests.assignment_run_finished(idle_robots=0)
    busy_for = livestate.client().pttl(step_requests.ASSIGNMENT_FLEET_BUSY_KEY) / 1000
    assert 0 < busy_for <= step_requests.tuning.ASSIGNMENT_FLEET_BUSY_SECONDS
    asked_at = datetime.now(UTC)
    step_requests.queue_assignment(defer_while_busy=True)
    eta = _eta(_assignment_tasks()[0])
    assert eta is not None and eta > asked_at + timedelta(seconds=busy_for / 2)

    step_requests.assignment_run_started()
    livestate.client().delete(step_requests.ASSIGNMENT_RAN_KEY)
    step_requests.queue_assignment()  # any other cause (a robot freed, changed, ...): at once
    assert _eta(_assignment_tasks()[0]) is None


@pytest.mark.parametrize("idle_robots", [2, None])
def test_a_run_that_left_robots_idle_or_did_not_count_them_lets_new_missions_ask_at_once(
    no_assignment_queued: None, idle_robots: int | None
) -> None:
    step_requests.assignment_run_finished(idle_robots=0)
    step_requests.assignment_run_finished(idle_robots=idle_robots)

    step_requests.queue_assignment(defer_while_busy=True)
    assert _eta(_assignment_tasks()[0]) is None


def test_the_sender_asks_for_one_run_whatever_mix_of_requests_came(no_assignment_queued: None) -> None:
    step_requests.queue_assignment_soon(defer_while_busy=True)
    step_requests.queue_assignment_soon()
    step_requests.queue_assignment_soon(defer_while_busy=True)

    assert step_requests.wait_until_queued(5.0)
    assert len(_assignment_tasks()) == 1


def test_a_run_asked_for_the_reasons_knows_it_even_when_a_plain_one_was_queued_first(
    no_assignment_queued: None,
) -> None:
    step_requests.queue_assignment()
    assert step_requests.assignment_run_started() is False

    step_requests.queue_assignment()
    step_requests.queue_assignment(with_reasons=True)  # beat's, while the plain one waits
    assert len(_assignment_tasks()) == 2  # one per run started: the second request queued none
    ttl = livestate.client().ttl(step_requests.ASSIGNMENT_MARKER_KEY)
    assert 0 < ttl <= step_requests.tuning.ASSIGNMENT_MARKER_SECONDS  # its expiry kept
    assert step_requests.assignment_run_started() is True


@pytest.fixture
def no_zones_plan_queued() -> Iterator[None]:
    def clear() -> None:
        redis = livestate.client()
        redis.delete(step_requests.ZONES_MARKER_KEY, step_requests.ZONES_RAN_KEY)
        for message in _tasks(step_requests.ZONES_TASK):
            redis.lrem(settings.STEP_QUEUE, 0, message)

    clear()
    yield
    clear()


def test_zone_plan_runs_are_coalesced_and_one_asked_for_right_after_a_run_started_waits_its_interval(
    no_zones_plan_queued: None,
) -> None:
    step_requests.queue_zones_plan()
    step_requests.queue_zones_plan()
    [first] = _tasks(step_requests.ZONES_TASK)
    assert _eta(first) is None  # no run started lately: at once
    ttl = livestate.client().ttl(step_requests.ZONES_MARKER_KEY)
    assert 0 < ttl <= step_requests.tuning.ZONES_MARKER_SECONDS  # a lost run blocks others only so long

    step_requests.zones_plan_started()  # what the run does first
    asked_at = datetime.now(UTC)
    step_requests.queue_zones_plan()
    sent_by = datetime.now(UTC)
    tasks = _tasks(step_requests.ZONES_TASK)
    assert len(tasks) == 2
    eta = _eta(tasks[0])  # the newest: Celery pushes on the list's left
    interval = timedelta(seconds=step_requests.tuning.ZONES_RUN_INTERVAL_SECONDS)
    assert eta is not None and asked_at < eta <= sent_by + interval


def test_zone_plan_runs_asked_soon_are_one_queued_by_the_sender_thread(no_zones_plan_queued: None) -> None:
    step_requests.queue_zones_plan_soon()
    step_requests.queue_zones_plan_soon()

    assert step_requests.wait_until_queued(5.0)
    assert len(_tasks(step_requests.ZONES_TASK)) == 1


@pytest.mark.django_db
def test_beat_queues_zone_plan_runs_only_while_a_map_has_an_enabled_zone_set(
    no_zones_plan_queued: None,
) -> None:
    zone_set = ZoneSetFactory()
    plan_zones_while_enabled()
    assert _tasks(step_requests.ZONES_TASK) == []  # no set enabled, no order held back

    zone_set_enable(actor=TEST_ACTOR, zone_set=zone_set)
    plan_zones_while_enabled()
    assert len(_tasks(step_requests.ZONES_TASK)) == 1  # (the enable's own request waits for a commit)
