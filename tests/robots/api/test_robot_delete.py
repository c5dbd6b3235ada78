"""DELETE /robot/{name}: removed at once, or PENDING_DELETE while it runs a mission."""

import pytest

from missions.models import Mission
from robots.models import Robot
from tests.factories import MissionFactory, RobotFactory

pytestmark = pytest.mark.django_db


def test_a_robot_without_a_running_mission_is_removed_at_once(api, woken):
    RobotFactory(name="carter01")

    response = api.delete("/robot/carter01")

    assert response.status_code == 200
    assert response.json() == {"detail": "carter01 is PENDING_DELETE"}
    assert api.get("/robot/carter01").json() == {"detail": 'Did not find "robot" with name "carter01"'}
    assert woken == ["carter01"]


def test_a_robot_running_a_mission_stays_pending_delete(api, woken):
    RobotFactory(name="carter01", state="ON_TASK")
    MissionFactory(robot="carter01", running=True)

    response = api.delete("/robot/carter01")

    assert response.json() == {"detail": "carter01 is PENDING_DELETE"}
    assert api.get("/robot/carter01").json()["lifecycle"] == "PENDING_DELETE"
    assert [robot["lifecycle"] for robot in api.get("/robot").json()] == ["PENDING_DELETE"]
    assert woken == ["carter01"]


def test_queued_missions_of_a_removed_robot_stay_pending(api):
    RobotFactory(name="carter01")
    mission = MissionFactory(robot="carter01")

    api.delete("/robot/carter01")

    assert not Robot.objects.exists()
    assert Mission.objects.get(name=mission.name).state == "PENDING"


def test_missions_of_other_robots_do_not_keep_a_robot(api):
    RobotFactory(name="carter01")
    MissionFactory(robot="carter02", running=True)

    api.delete("/robot/carter01")

    assert not Robot.objects.filter(name="carter01").exists()


def test_missing_robot_is_400_with_the_reference_message(api):
    response = api.delete("/robot/carter99")

    assert response.status_code == 400
    assert response.json() == {"detail": "Could not find object carter99"}
