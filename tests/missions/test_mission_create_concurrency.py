"""mission_create racing a step of its robot, outside a test's transaction (as the API and the bridge run
them), each on a connection of its own. A mission created while a step ends the robot's last one may be
missed by both (the step read the queue before the INSERT committed, the INSERT saw the mission still
RUNNING), and would wait for beat's sweep. The robot's queue lock orders the two: exactly one of them
starts the mission, the step itself (a transaction more) or the creation (it wakes the robot)."""

import threading
import time
import uuid
from collections.abc import Callable, Iterator
from functools import partial
from typing import Any

import pytest
from django.db import connection, transaction

import missions.robot_step
import missions.services
from kit.api.errors import ObjectError
from missions.models import Mission
from missions.robot_step import robot_step
from missions.services import mission_create
from robots import livestate
from robots.models import InstantAction, Robot
from robots.services import robot_create
from tests.database import other_connection
from tests.dispatch.builders import finished
from tests.factories import TEST_ACTOR, route_node
from tests.missions.test_robot_step import orders, put_state
from vda5050.models import ActionStatus

pytestmark = pytest.mark.django_db(transaction=True)

MISSIONS = Mission._meta.db_table
CREATION_THREAD = "creation"
STEP_THREAD = "step"


def spec(robot: str) -> dict[str, Any]:
    return {"robot": robot, "mission_tree": [route_node("goto")]}


class OnItsOwnConnection:
    """A service call on a thread of its own, with its own database connection; `start` returns once the
    connection is open (its server process's id in `backend_pid`), `result` is what the call returned."""

    def __init__(self, call: Callable[[], object], thread_name: str) -> None:
        self.call = call
        self.backend_pid: int | None = None
        self.result: object = None
        self.error: BaseException | None = None
        self._connected = threading.Event()
        self._thread = threading.Thread(target=self._run, name=thread_name)

    def start(self) -> "OnItsOwnConnection":
        self._thread.start()
        assert self._connected.wait(10)
        return self

    def done(self, timeout: float) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _run(self) -> None:
        try:
            connection.ensure_connection()
            self.backend_pid = connection.connection.info.backend_pid
            self._connected.set()
            self.result = self.call()
        except BaseException as error:  # the test reads it
            self.error = error
        finally:
            self._connected.set()
            connection.close()


def creation(name: str, robot: str) -> OnItsOwnConnection:
    """mission_create on the thread named CREATION_THREAD."""
    call = partial(mission_create, actor=TEST_ACTOR, name=name, prefix=None, spec=spec(robot))
    return OnItsOwnConnection(call, CREATION_THREAD)


def step(robot: str) -> OnItsOwnConnection:
    """robot_step on the thread named STEP_THREAD."""
    return OnItsOwnConnection(partial(robot_step, name=robot), STEP_THREAD)


@pytest.fixture
def wakes(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, str]]:
    """(robot, thread) per wake-up the mission services asked for: the creation's thread or the step's."""
    calls: list[tuple[str, str]] = []

    def request_steps(names: list[str]) -> None:
        calls.extend((name, threading.current_thread().name) for name in names)

    monkeypatch.setattr(missions.services, "request_steps", request_steps)
    return calls


@pytest.fixture
def robot(wakes: list[tuple[str, str]]) -> Iterator[Robot]:
    """An online robot whose one mission, "last", runs, and whose latest state says its order is done: the
    next step ends "last" and finds the queue empty."""
    created = robot_create(actor=TEST_ACTOR, name=f"race-{uuid.uuid4().hex[:10]}", prefix=None, spec={})
    Robot.objects.filter(name=created.name).update(online=True)
    InstantAction.objects.filter(robot=created).update(status=ActionStatus.FINISHED.value)
    put_state(created, header_id=1)
    mission_create(actor=TEST_ACTOR, name="last", prefix=None, spec=spec(created.name))
    [order] = orders(robot_step(name=created.name))
    put_state(created, header_id=2, state=finished(order))
    wakes.clear()
    yield created
    livestate.forget(created.name)


def wait_until(condition: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return False


def waits_for_a_lock(pid: int) -> bool:
    with other_connection() as observer:
        row = observer.execute(
            "SELECT wait_event_type FROM pg_stat_activity WHERE pid = %s", [pid]
        ).fetchone()
    return row is not None and row[0] == "Lock"


def holds_an_advisory_lock(pid: int) -> bool:
    with other_connection() as observer:
        sql = "SELECT EXISTS (SELECT 1 FROM pg_locks WHERE pid = %s AND locktype = 'advisory' AND granted)"
        return observer.execute(sql, [pid]).fetchone()[0]


def test_a_mission_created_after_the_steps_last_look_at_the_queue_is_started_by_the_step(
    robot: Robot, wakes: list[tuple[str, str]], monkeypatch: pytest.MonkeyPatch
) -> None:
    creations: list[OnItsOwnConnection] = []
    records = missions.robot_step.mission_records

    def read_queue_then_create(rows: list[Any]) -> list[Any]:
        """The step's read of the queue ("last" alone: its whole queue, not read again once "last" is
        done); the creation commits right after it."""
        upcoming = records(rows)
        if not creations:
            creations.append(creation("next", robot.name).start())
            assert creations[0].done(timeout=10)
        return upcoming

    monkeypatch.setattr(missions.robot_step, "mission_records", read_queue_then_create)

    outcome = robot_step(name=robot.name)

    assert creations[0].error is None
    assert [m.name for m in outcome.finished] == ["last"]
    # "next" came after the step's read of the queue, and the creation saw "last" still running (no
    # wake-up); the step's look under the queue lock saw "next", and its transaction more started it.
    [order] = orders(outcome)
    assert order.order_id.startswith("next-")
    assert outcome.header_ids == [1]  # the first order sent for "last" had 0
    assert wakes == []
    assert Mission.objects.get(name="next").state == "RUNNING"


def test_a_step_that_ends_the_last_mission_waits_for_a_creation_in_flight_and_starts_it(
    robot: Robot, wakes: list[tuple[str, str]]
) -> None:
    release = threading.Event()

    def create_and_hold() -> None:
        """The creation inside a transaction that stays open (holding the queue lock) until released."""
        with transaction.atomic():
            mission_create(actor=TEST_ACTOR, name="next", prefix=None, spec=spec(robot.name))
            assert release.wait(10)

    creating = OnItsOwnConnection(create_and_hold, CREATION_THREAD).start()
    assert wait_until(lambda: holds_an_advisory_lock(creating.backend_pid))
    stepping = step(robot.name).start()

    assert wait_until(lambda: waits_for_a_lock(stepping.backend_pid))
    assert Mission.objects.get(name="last").state == "RUNNING"  # the step waits before its COMMIT
    release.set()
    assert creating.done(timeout=10)
    assert stepping.done(timeout=10)
    assert (creating.error, stepping.error) == (None, None)
    # The creation saw "last" running; the step's look waited for it, and saw "next".
    [order] = orders(stepping.result)
    assert order.order_id.startswith("next-")
    assert wakes == []


def test_a_mission_whose_insert_waited_while_a_step_ended_the_last_one_wakes_the_robot(
    robot: Robot, wakes: list[tuple[str, str]]
) -> None:
    with other_connection() as other:
        # Another transaction's row of the same name, not committed: the creation's INSERT waits for it.
        other.execute(f"CREATE TEMP TABLE copy AS SELECT * FROM {MISSIONS} WHERE name = 'last'")
        other.execute("UPDATE copy SET name = 'next', state = 'PENDING'")
        other.execute(f"INSERT INTO {MISSIONS} SELECT * FROM copy")
        creating = creation("next", robot.name).start()
        assert wait_until(lambda: waits_for_a_lock(creating.backend_pid))

        outcome = robot_step(name=robot.name)  # "next" is not there yet for it

        assert [m.name for m in outcome.finished] == ["last"]
        assert orders(outcome) == []
        other.rollback()
    assert creating.done(timeout=10)
    assert creating.error is None
    # Its INSERT's snapshot was taken while "last" ran; its look at the queue, after the wait, was not.
    assert wakes == [(robot.name, CREATION_THREAD)]


def test_a_creation_that_waits_for_a_steps_queue_lock_wakes_the_robot_and_the_step_does_not_start_it(
    robot: Robot, wakes: list[tuple[str, str]]
) -> None:
    with other_connection() as other:
        # A creation's look at the queue without a mission of its own, holding the lock shared: the step
        # that ends "last" waits for it before its look and COMMIT, and the creation that comes next
        # queues behind the step.
        other.execute("SELECT mission_queued_behind(%s, 0)", [robot.name])
        stepping = step(robot.name).start()
        assert wait_until(lambda: waits_for_a_lock(stepping.backend_pid))
        creating = creation("next", robot.name).start()
        assert wait_until(lambda: waits_for_a_lock(creating.backend_pid))
        other.rollback()
    assert stepping.done(timeout=10)
    assert creating.done(timeout=10)
    assert (stepping.error, creating.error) == (None, None)
    # The step's look came before the creation committed: it ended "last" and stopped there. The creation
    # looked after the step's commit, saw no mission left before "next", and woke the robot: one start.
    assert [m.name for m in stepping.result.finished] == ["last"]
    assert orders(stepping.result) == []
    assert wakes == [(robot.name, CREATION_THREAD)]
    assert Mission.objects.get(name="next").state == "PENDING"


def test_a_mission_created_while_the_robots_mission_runs_does_not_wake_it(
    robot: Robot, wakes: list[tuple[str, str]]
) -> None:
    mission_create(actor=TEST_ACTOR, name="next", prefix=None, spec=spec(robot.name))

    assert wakes == []  # the step that ends "last" starts it
    outcome = robot_step(name=robot.name)
    assert [m.name for m in outcome.finished] == ["last"]
    [order] = orders(outcome)
    assert order.order_id.startswith("next-")
    assert wakes == []


def test_a_creation_for_a_robot_that_does_not_exist_yet_is_stored_and_wakes_it(
    wakes: list[tuple[str, str]],
) -> None:
    mission = mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec("carter01"))

    assert Mission.objects.get(name="m1").queue_position == mission.queue_position
    assert wakes == [("carter01", "MainThread")]


def test_a_duplicate_name_is_an_object_error_and_leaves_the_connection_usable(
    wakes: list[tuple[str, str]],
) -> None:
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec("carter01"))

    with pytest.raises(ObjectError, match="Object mission with name m1 already exists"):
        mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec("carter01"))

    assert Mission.objects.filter(name="m1").count() == 1
    mission_create(actor=TEST_ACTOR, name="m2", prefix=None, spec=spec("carter01"))
    assert wakes == [("carter01", "MainThread")]  # m1 woke it; m2 is queued behind m1
