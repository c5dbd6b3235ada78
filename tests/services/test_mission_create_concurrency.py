"""mission_create against a robot's step and the bridge's status writes, outside a test's transaction (as the
API runs it), each held open on a connection of its own."""

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import psycopg
import pytest
from django.db import connection

from fleet.api import ObjectError
from missions.models import Mission
from missions.services import CURRENT_MISSIONS_SQL, ROBOT_FOR_STEP_SQL, mission_create
from robots.models import Robot
from tests.database import other_connection
from tests.factories import MissionFactory, RobotFactory, route_node

pytestmark = pytest.mark.django_db(transaction=True)

ROBOT = "carter01"
ROBOTS = Robot._meta.db_table
MISSIONS = Mission._meta.db_table


def spec() -> dict[str, Any]:
    return {"robot": ROBOT, "mission_tree": [route_node("goto")]}


class Creation:
    """mission_create on a thread of its own, with its own database connection."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.backend_pid: int | None = None
        self.error: BaseException | None = None
        self._connected = threading.Event()
        self._thread = threading.Thread(target=self._run)

    def start(self) -> "Creation":
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
            mission_create(name=self.name, prefix=None, spec=spec())
        except BaseException as error:  # the test reads it
            self.error = error
        finally:
            self._connected.set()
            connection.close()


@pytest.fixture
def held() -> Iterator[psycopg.Connection]:
    """Another server process's open transaction (a step's, a status write's), rolled back at the end."""
    with other_connection() as other:
        yield other
        other.rollback()


def wait_until(condition: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return False


def step_in_flight(held: psycopg.Connection, mission: str, state: str) -> None:
    """A step's reads on `held` (locking the robot and its current missions), then its write of `mission`,
    not yet committed."""
    held.execute(ROBOT_FOR_STEP_SQL, [ROBOT])
    held.execute(CURRENT_MISSIONS_SQL, [ROBOT, 2])
    held.execute(f"UPDATE {MISSIONS} SET state = %s WHERE name = %s", [state, mission])


def waits_for_a_lock(pid: int) -> bool:
    with other_connection() as observer:
        row = observer.execute(
            "SELECT wait_event_type FROM pg_stat_activity WHERE pid = %s", [pid]
        ).fetchone()
    return row is not None and row[0] == "Lock"


def test_a_mission_created_while_a_step_ends_the_robots_last_one_wakes_the_robot(held, woken) -> None:
    RobotFactory(name=ROBOT)
    MissionFactory(name="last", robot=ROBOT, running=True)
    # Its read of the queue found nothing after "last", which it ends.
    step_in_flight(held, "last", "COMPLETED")

    creation = Creation("next").start()

    assert wait_until(lambda: waits_for_a_lock(creation.backend_pid))  # for the step, not past it
    assert woken == []
    held.commit()
    assert creation.done(timeout=10)
    assert creation.error is None
    assert woken == [ROBOT]  # the step ended the last mission and did not see this one: it needs a step
    assert Mission.objects.get(name="next").state == "PENDING"


def test_a_mission_created_while_a_step_starts_the_one_before_it_does_not_wake_the_robot(held, woken) -> None:
    RobotFactory(name=ROBOT)
    MissionFactory(name="first", robot=ROBOT)
    step_in_flight(held, "first", "RUNNING")

    creation = Creation("second").start()

    assert wait_until(lambda: waits_for_a_lock(creation.backend_pid))
    held.commit()
    assert creation.done(timeout=10)
    assert creation.error is None
    assert woken == []  # the step that ends "first" starts it


def test_a_creation_does_not_wait_for_the_bridges_status_write(held, woken) -> None:
    RobotFactory(name=ROBOT)
    held.execute(f"UPDATE {ROBOTS} SET battery_level = 5 WHERE name = %s", [ROBOT])  # uncommitted

    creation = Creation("m1").start()

    assert creation.done(timeout=10)
    assert creation.error is None
    assert woken == [ROBOT]


def test_a_creation_for_a_robot_that_does_not_exist_yet_is_stored_and_wakes_it(woken) -> None:
    mission = mission_create(name="m1", prefix=None, spec=spec())

    assert Mission.objects.get(name="m1").queue_position == mission.queue_position
    assert woken == [ROBOT]


def test_a_duplicate_name_is_an_object_error_and_leaves_the_connection_usable(woken) -> None:
    mission_create(name="m1", prefix=None, spec=spec())

    with pytest.raises(ObjectError, match="Object mission with name m1 already exists"):
        mission_create(name="m1", prefix=None, spec=spec())

    assert Mission.objects.filter(name="m1").count() == 1
    mission_create(name="m2", prefix=None, spec=spec())
    assert woken == [ROBOT]  # m1 woke it; m2 is queued behind m1
