"""PUT /robot/{name}: replaces the whole spec."""

import pytest
from django.conf import settings

from robots.models import Robot
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db


def test_put_replaces_the_spec(api, woken):
    RobotFactory(name="carter01")

    response = api.put(
        "/robot/carter01",
        {
            "labels": ["dock"],
            "battery": {"critical_level": 5, "recommended_minimum": 20},
            "heartbeat_timeout": 2.5,
        },
    )

    assert response.status_code == 200
    body = response.json()
    assert body["labels"] == ["dock"]
    assert body["battery"] == {
        "critical_level": 5.0,
        "recommended_minimum": 20.0,
        "recommended_maximum": None,
    }
    assert body["heartbeat_timeout"] == 2.5
    assert Robot.objects.get(name="carter01").heartbeat_timeout == 2.5
    assert woken == ["carter01"]


def test_fields_the_body_omits_go_back_to_their_defaults(api):
    RobotFactory(
        name="carter01",
        labels=["dock"],
        battery_critical_level=5.0,
        battery_recommended_minimum=20.0,
        heartbeat_timeout=2.0,
        switch_teleop=True,
        manufacturer="Acme",
        serial_number="SN-1",
        protocol_version="2.1.0",
        instant_actions_key="instantActions",
    )

    response = api.put("/robot/carter01", {})

    assert response.status_code == 200
    body = response.json()
    assert body["labels"] == []
    assert body["battery"] == {
        "critical_level": 10.0,
        "recommended_minimum": None,
        "recommended_maximum": None,
    }
    assert (body["heartbeat_timeout"], body["switch_teleop"]) == (30.0, False)
    assert body["vda5050"] == {
        "interface_name": settings.VDA5050_INTERFACE_NAME,
        "manufacturer": settings.VDA5050_MANUFACTURER,
        "serial_number": "carter01",
        "version": settings.VDA5050_VERSION,
        "version_source": "DEFAULT",
        "instant_actions_key": "actions",
        "instant_actions_key_source": "DEFAULT",
        "compatibility_rules": [],
    }


def test_put_keeps_the_status(api):
    RobotFactory(name="carter01", online=True, battery_level=55.0, state="ON_TASK")

    status = api.put("/robot/carter01", {"heartbeat_timeout": 5}).json()["status"]

    assert (status["online"], status["battery_level"], status["state"]) == (True, 55.0, "ON_TASK")


def test_missing_robot_is_400_with_the_reference_message(api):
    response = api.put("/robot/carter99", {})

    assert response.status_code == 400
    assert response.json() == {"detail": "Could not find object carter99"}


def test_status_in_the_body_is_a_usage_error(api):
    RobotFactory(name="carter01")

    response = api.put("/robot/carter01", {"status": {"online": True}})

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert Robot.objects.get(name="carter01").online is False


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"name": "carter02"}, ["body", "name"]),
        ({"prefix": "carter"}, ["body", "prefix"]),
        ({"heartbeat_timeout": 0}, ["body", "heartbeat_timeout"]),
        ({"battery": {"level": 3}}, ["body", "battery", "level"]),
    ],
)
def test_invalid_bodies_are_400(api, body, loc):
    RobotFactory(name="carter01", heartbeat_timeout=7.0)

    response = api.put("/robot/carter01", body)

    assert response.status_code == 400
    assert [error["loc"] for error in response.json()["detail"]] == [loc]
    assert Robot.objects.get(name="carter01").heartbeat_timeout == 7.0


def test_a_vda5050_identity_in_use_is_a_usage_error(api):
    RobotFactory(name="carter01")
    RobotFactory(name="carter02")

    response = api.put("/robot/carter02", {"vda5050": {"serial_number": "carter01"}})

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert Robot.objects.get(name="carter02").serial_number == "carter02"


def test_put_keeps_learned_protocol_settings_and_an_operators_choice_wins(api):
    """What the robot showed it speaks survives a PUT that omits it; a PUT that gives it is final."""
    RobotFactory(
        name="carter01",
        protocol_version="3.0.0",
        protocol_version_source="LEARNED",
        instant_actions_key="instantActions",
        instant_actions_key_source="LEARNED",
    )

    kept = api.put("/robot/carter01", {}).json()["vda5050"]
    chosen = api.put("/robot/carter01", {"vda5050": {"instant_actions_key": "actions"}}).json()["vda5050"]

    assert (kept["version"], kept["version_source"]) == ("3.0.0", "LEARNED")
    assert (kept["instant_actions_key"], kept["instant_actions_key_source"]) == ("instantActions", "LEARNED")
    assert (chosen["instant_actions_key"], chosen["instant_actions_key_source"]) == ("actions", "OPERATOR")
    assert (chosen["version"], chosen["version_source"]) == ("3.0.0", "LEARNED")
