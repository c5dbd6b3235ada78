"""POST /robot/{name}/charge: an operator sends a robot to charge now (issue 44)."""

import pytest

from access.models import WriteRecord
from robots.models import Robot
from tests.factories import CAN_CHARGE, RobotFactory

pytestmark = pytest.mark.django_db


def test_a_robot_that_can_charge_is_asked_to_and_the_write_recorded(api):
    RobotFactory(name="carter01", online=True, factsheet=CAN_CHARGE)

    response = api.post("/robot/carter01/charge")

    assert response.status_code == 200
    body = response.json()
    assert body["name"] == "carter01"
    assert body["status"]["charge_requested"] is True
    assert Robot.objects.get(name="carter01").charge_requested is True
    assert WriteRecord.objects.filter(action="robot_charge", object_name="carter01").exists()


def test_a_3_0_factsheet_lists_its_actions_as_mobile_robot_actions(api):
    factsheet = {"protocolFeatures": {"mobileRobotActions": [{"actionType": "startCharging"}]}}
    RobotFactory(name="carter01", online=True, factsheet=factsheet)

    assert api.post("/robot/carter01/charge").status_code == 200


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        pytest.param(
            {"online": False, "factsheet": CAN_CHARGE},
            "Robot carter01 is offline: it cannot be sent to charge.",
            id="offline",
        ),
        pytest.param(
            {"online": True, "factsheet": CAN_CHARGE, "state": "CHARGING"},
            "Robot carter01 is charging already.",
            id="charging",
        ),
        pytest.param(
            {"online": True, "factsheet": None},
            "Robot carter01 cannot be sent to charge: its factsheet lists no startCharging.",
            id="no-factsheet",
        ),
        pytest.param(
            {"online": True, "factsheet": {"protocolFeatures": {"agvActions": [{"actionType": "pick"}]}}},
            "Robot carter01 cannot be sent to charge: its factsheet lists no startCharging.",
            id="no-start-charging",
        ),
    ],
)
def test_a_robot_that_cannot_charge_is_a_usage_error_and_nothing_changes(api, fields, message):
    RobotFactory(name="carter01", **fields)

    response = api.post("/robot/carter01/charge")

    assert response.status_code == 400
    assert response.json() == {"message": message, "error_code": "USAGE"}
    assert Robot.objects.get(name="carter01").charge_requested is False
    assert not WriteRecord.objects.filter(action="robot_charge").exists()


def test_missing_robot_is_400_with_the_reference_message(api):
    response = api.post("/robot/carter99/charge")

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "robot" with name "carter99"'}


def test_charge_is_post_only_and_takes_no_body(api):
    RobotFactory(name="carter01", online=True, factsheet=CAN_CHARGE)

    assert api.get("/robot/carter01/charge").status_code == 405
