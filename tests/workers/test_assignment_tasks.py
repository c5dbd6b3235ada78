"""The assignment tasks (`workers.tasks.assign_missions`, `assign_waiting`): thin, over the service and the
coalesced request; real PostgreSQL and Redis."""

import pytest
from django.conf import settings
from django.utils import timezone

from missions.models import Mission
from missions.services import mission_create
from robots import livestate
from tests.factories import TEST_ACTOR, RobotFactory
from tests.workers.test_step_requests import _assignment_tasks, no_assignment_queued  # noqa: F401
from workers import step_requests
from workers.tasks import assign_missions, assign_waiting

pytestmark = pytest.mark.django_db(transaction=True)

ROUTE = {"route": {"waypoints": [{"x": 1, "y": 0, "map_id": "map"}]}}


def test_a_run_clears_its_marker_and_binds(no_assignment_queued: None) -> None:  # noqa: F811
    RobotFactory(name="free", online=True, battery_level=80.0, last_state_at=timezone.now())
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec={"mission_tree": [ROUTE]})
    assert step_requests.wait_until_queued(5.0)  # the creation's request: marked and queued
    assert livestate.client().exists(step_requests.ASSIGNMENT_MARKER_KEY)

    assign_missions()

    assert not livestate.client().exists(step_requests.ASSIGNMENT_MARKER_KEY)
    assert Mission.objects.get(name="m1").robot == "free"


def test_beat_asks_for_a_run_only_while_unbound_missions_wait(no_assignment_queued: None) -> None:  # noqa: F811
    assign_waiting()
    assert _assignment_tasks() == []

    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec={"mission_tree": [ROUTE]})
    assert step_requests.wait_until_queued(5.0)
    livestate.client().delete(step_requests.ASSIGNMENT_MARKER_KEY)  # the creation's own request, run
    for message in _assignment_tasks():
        livestate.client().lrem(settings.STEP_QUEUE, 0, message)
    assign_waiting()
    assert len(_assignment_tasks()) == 1


def test_a_run_says_whether_it_left_a_free_robot_idle(no_assignment_queued: None) -> None:  # noqa: F811
    busy = step_requests.ASSIGNMENT_FLEET_BUSY_KEY
    RobotFactory(name="r1", online=True, battery_level=80.0, last_state_at=timezone.now())
    for name in ("m1", "m2"):
        mission_create(actor=TEST_ACTOR, name=name, prefix=None, spec={"mission_tree": [ROUTE]})

    assign_missions()
    assert Mission.objects.exclude(robot=None).count() == 1
    assert livestate.client().exists(busy)  # r1 took one: no robot idle, m2 waits for one to fall free

    Mission.objects.filter(robot="r1").delete()
    Mission.objects.filter(name="m2").delete()
    assign_missions()
    assert not livestate.client().exists(busy)  # r1 is idle again: a new mission asks for a run
