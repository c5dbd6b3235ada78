"""POST /robot: the README robot, naming, defaults, the VDA 5050 identity, and every validation rule."""

import re

import pytest
from django.conf import settings

from robots.models import Robot
from tests.factories import RobotFactory
from tests.readme import README_ROBOT

pytestmark = pytest.mark.django_db

GENERATED_NAME = re.compile(r"[a-z2-7]{26}")


def test_readme_robot_is_created_with_the_reference_shape(api, woken):
    response = api.post("/robot", README_ROBOT)

    assert response.status_code == 200
    assert response.json() == {
        "labels": [],
        "battery": {"critical_level": 0.1, "recommended_minimum": None, "recommended_maximum": None},
        "heartbeat_timeout": 30.0,
        "switch_teleop": False,
        "vda5050": {
            "interface_name": settings.VDA5050_INTERFACE_NAME,
            "manufacturer": settings.VDA5050_MANUFACTURER,
            "serial_number": "carter01",
            "version": settings.VDA5050_VERSION,
            "version_source": "DEFAULT",
            "instant_actions_key": "actions",
            "instant_actions_key_source": "DEFAULT",
            "compatibility_rules": [],
        },
        "name": "carter01",
        "status": {
            "pose": {
                "x": 0.0,
                "y": 0.0,
                "theta": 0.0,
                "map_id": "",
                "allowedDeviationXY": 0.1,
                "allowedDeviationTheta": 0.0,
            },
            "position_initialized": False,
            "software_version": {"os": "", "app": ""},
            "hardware_version": {"manufacturer": "", "serial_number": ""},
            "factsheet": {"agv_class": "CARRIER", "speed_max": -1.0, "supported_zones": []},
            "online": False,
            "battery_level": 0.0,
            "state": "IDLE",
            "state_since": None,
            "operating_mode": "",
            "info_messages": None,
            "errors": {},
            "maps": [],
            "zone_sets": [],
            "zone_access": {"held": [], "waiting": []},
            "charge_requested": False,
            "charging_waiting_reason": None,
        },
        "lifecycle": "ALIVE",
    }
    assert Robot.objects.get(name="carter01").battery_critical_level == 0.1
    assert woken == ["carter01"]


def test_empty_body_creates_a_robot_with_a_generated_name_and_defaults(api):
    response = api.post("/robot", {})

    assert response.status_code == 200
    body = response.json()
    assert GENERATED_NAME.fullmatch(body["name"])
    assert body["vda5050"]["serial_number"] == body["name"]
    assert (body["labels"], body["heartbeat_timeout"], body["switch_teleop"]) == ([], 30.0, False)
    assert body["battery"] == {
        "critical_level": 10.0,
        "recommended_minimum": None,
        "recommended_maximum": None,
    }


def test_prefix_gives_prefix_dash_generated_id(api):
    response = api.post("/robot", {"prefix": "carter"})

    assert response.status_code == 200
    prefix, generated = response.json()["name"].split("-")
    assert prefix == "carter"
    assert GENERATED_NAME.fullmatch(generated)


def test_two_unnamed_robots_get_different_names(api):
    first = api.post("/robot", {}).json()["name"]
    second = api.post("/robot", {}).json()["name"]

    assert first != second


def test_the_longest_prefix_still_gives_a_valid_name(api):
    response = api.post("/robot", {"prefix": "p" * 73})

    assert response.status_code == 200
    assert len(response.json()["name"]) == 100


def test_name_and_prefix_together_are_a_usage_error(api):
    response = api.post("/robot", {"name": "carter01", "prefix": "carter"})

    assert response.status_code == 400
    assert response.json() == {"message": 'Cannot have both "name" and "prefix"', "error_code": "USAGE"}


def test_duplicate_name_is_refused_with_the_reference_message(api):
    RobotFactory(name="carter01")

    response = api.post("/robot", {"name": "carter01"})

    assert response.status_code == 400
    assert response.json() == {"detail": "Object robot with name carter01 already exists"}


def test_status_in_the_body_is_a_usage_error(api):
    response = api.post("/robot", {"name": "carter01", "status": {"online": True}})

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert "status" in response.json()["message"]
    assert not Robot.objects.exists()


def test_vda5050_identity_is_stored_and_returned(api):
    identity = {
        "interface_name": "fleet2",
        "manufacturer": "Acme",
        "serial_number": "SN-0001",
        "version": "2.1.0",
        "instant_actions_key": "instantActions",
    }

    response = api.post("/robot", {"name": "carter01", "vda5050": identity})

    assert response.status_code == 200
    assert response.json()["vda5050"] == {
        **identity,
        "version_source": "OPERATOR",
        "instant_actions_key_source": "OPERATOR",
        "compatibility_rules": [],
    }
    robot = Robot.objects.get(name="carter01")
    assert (robot.interface_name, robot.manufacturer, robot.serial_number) == ("fleet2", "Acme", "SN-0001")
    assert (robot.protocol_version, robot.instant_actions_key) == ("2.1.0", "instantActions")


def test_vda5050_fields_left_out_take_their_defaults(api):
    response = api.post("/robot", {"name": "carter01", "vda5050": {"manufacturer": "Acme"}})

    assert response.json()["vda5050"] == {
        "interface_name": settings.VDA5050_INTERFACE_NAME,
        "manufacturer": "Acme",
        "serial_number": "carter01",
        "version": settings.VDA5050_VERSION,
        "version_source": "DEFAULT",
        "instant_actions_key": "actions",
        "instant_actions_key_source": "DEFAULT",
        "compatibility_rules": [],
    }


def test_a_vda5050_identity_in_use_is_a_usage_error(api):
    RobotFactory(name="carter01")

    response = api.post("/robot", {"name": "other", "vda5050": {"serial_number": "carter01"}})

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert "serial_number=carter01" in response.json()["message"]
    assert not Robot.objects.filter(name="other").exists()


@pytest.mark.parametrize(
    ("body", "loc", "error_type"),
    [
        ({"color": "red"}, ["body", "color"], "extra_forbidden"),
        ({"battery": {"critical_level": 1, "volts": 48}}, ["body", "battery", "volts"], "extra_forbidden"),
        ({"vda5050": {"serial": "x"}}, ["body", "vda5050", "serial"], "extra_forbidden"),
        ({"heartbeat_timeout": "soon"}, ["body", "heartbeat_timeout"], "invalid"),
        ({"heartbeat_timeout": 0}, ["body", "heartbeat_timeout"], "greater_than"),
        ({"heartbeat_timeout": -5}, ["body", "heartbeat_timeout"], "greater_than"),
        ({"labels": "warehouse"}, ["body", "labels"], "not_a_list"),
        ({"labels": [["a"]]}, ["body", "labels", 0], "invalid"),
        ({"battery": 5}, ["body", "battery"], "invalid"),
        ({"battery": None}, ["body", "battery"], "null"),
        ({"switch_teleop": "sometimes"}, ["body", "switch_teleop"], "invalid"),
        ({"vda5050": {"version": "3.1.0"}}, ["body", "vda5050", "version"], "invalid_choice"),
        (
            {"vda5050": {"instant_actions_key": "acts"}},
            ["body", "vda5050", "instant_actions_key"],
            "invalid_choice",
        ),
        ({"vda5050": {"manufacturer": "Acme/Robots"}}, ["body", "vda5050", "manufacturer"], "invalid_name"),
        ({"name": "carter 01"}, ["body", "name"], "invalid_name"),
        ({"name": "carter/01"}, ["body", "name"], "invalid_name"),
        ({"name": "carter#"}, ["body", "name"], "invalid_name"),
        ({"name": "c" * 101}, ["body", "name"], "max_length"),
        ({"name": ""}, ["body", "name"], "blank"),
        ({"prefix": "p" * 74}, ["body", "prefix"], "max_length"),
        ({"prefix": "a+b"}, ["body", "prefix"], "invalid_name"),
    ],
)
def test_invalid_bodies_are_400_with_fastapi_shaped_errors(api, body, loc, error_type):
    response = api.post("/robot", body)

    assert response.status_code == 400
    assert {"loc": loc, "type": error_type} in [
        {"loc": error["loc"], "type": error["type"]} for error in response.json()["detail"]
    ]
    assert all(error["msg"] for error in response.json()["detail"])
    assert not Robot.objects.exists()


def test_unknown_fields_are_reported_with_the_other_errors(api):
    response = api.post("/robot", {"heartbeat_timeout": -1, "colour": "red"})

    assert sorted(error["loc"][1] for error in response.json()["detail"]) == ["colour", "heartbeat_timeout"]
    unknown = next(error for error in response.json()["detail"] if error["loc"] == ["body", "colour"])
    assert "heartbeat_timeout" in unknown["msg"]


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_json_literals_are_refused(api, literal):
    response = api.post(
        "/robot", f'{{"name": "carter01", "heartbeat_timeout": {literal}}}', content_type="application/json"
    )

    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["body"]
    assert not Robot.objects.exists()


def test_numbers_too_large_for_a_float_are_refused(api):
    # Python's JSON parser reads 1e999 as infinity without complaint.
    response = api.post("/robot", '{"heartbeat_timeout": 1e999}', content_type="application/json")

    assert response.status_code == 400
    assert response.json()["detail"] == [
        {"loc": ["body", "heartbeat_timeout"], "msg": "A finite number is required.", "type": "invalid"}
    ]


def test_malformed_json_is_400(api):
    response = api.post("/robot", '{"name": ', content_type="application/json")

    assert response.status_code == 400
    assert response.json()["detail"][0]["type"] == "json_invalid"


def test_a_body_that_is_not_json_is_400(api):
    response = api.post("/robot", "name=carter01", content_type="application/x-www-form-urlencoded")

    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["body"]
    assert not Robot.objects.exists()


def test_a_body_that_is_not_an_object_is_400(api):
    response = api.post("/robot", [{"name": "carter01"}])

    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["body"]


def test_names_may_use_dots_colons_dashes_and_underscores(api):
    response = api.post("/robot", {"name": "site-1:carter_01.a"})

    assert response.status_code == 200
    assert api.get("/robot/site-1:carter_01.a").json()["name"] == "site-1:carter_01.a"
