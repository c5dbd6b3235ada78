"""POST /robot/{name}/teleop?params=START|STOP."""

import pytest

from robots.models import Robot
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db


@pytest.mark.parametrize("state", ["IDLE", "ON_TASK", "MAP_DEPLOYMENT", "TELEOP"])
def test_start_is_accepted_in_the_allowed_states(api, woken, state):
    RobotFactory(name="carter01", state=state)

    response = api.post("/robot/carter01/teleop?params=START")

    assert response.status_code == 200
    assert response.json() == "START teleop action received."
    assert Robot.objects.get(name="carter01").switch_teleop is True
    assert woken == ["carter01"]


def test_start_while_charging_is_a_usage_error(api, woken):
    RobotFactory(name="carter01", state="CHARGING")

    response = api.post("/robot/carter01/teleop?params=START")

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert "CHARGING" in response.json()["message"]
    assert Robot.objects.get(name="carter01").switch_teleop is False
    assert woken == []


@pytest.mark.parametrize("state", ["TELEOP", "CHARGING", "IDLE"])
def test_stop_is_accepted_in_any_state(api, state):
    RobotFactory(name="carter01", state=state, switch_teleop=True)

    response = api.post("/robot/carter01/teleop?params=STOP")

    assert response.json() == "STOP teleop action received."
    assert Robot.objects.get(name="carter01").switch_teleop is False


@pytest.mark.parametrize(
    ("query", "error_type"),
    [("", "required"), ("?params=PAUSE", "invalid_choice"), ("?params=start", "invalid_choice")],
)
def test_params_must_be_start_or_stop(api, query, error_type):
    RobotFactory(name="carter01")

    response = api.post(f"/robot/carter01/teleop{query}")

    assert response.status_code == 400
    assert [(error["loc"], error["type"]) for error in response.json()["detail"]] == [
        (["query", "params"], error_type)
    ]


def test_missing_robot_is_400_with_the_reference_message(api):
    response = api.post("/robot/carter99/teleop?params=START")

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "robot" with name "carter99"'}


def test_teleop_is_post_only(api):
    RobotFactory(name="carter01")

    assert api.get("/robot/carter01/teleop?params=START").status_code == 405
