"""GET /robot/{name}."""

from datetime import UTC, datetime

import pytest

from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db


def test_returns_the_robot_with_its_status(api):
    RobotFactory(
        name="carter01",
        pose_x=4.0,
        pose_y=5.0,
        pose_theta=1.5,
        pose_map_id="map",
        online=True,
        battery_level=42.0,
        state="ON_TASK",
        state_since=datetime(2026, 11, 28, 4, 30, tzinfo=UTC),
        operating_mode="AUTOMATIC",
        hardware_version={"manufacturer": "RobotCompany", "serial_number": "carter01"},
        software_version={"os": "linux"},
        agv_class="FORKLIFT",
        speed_max=1.5,
        info_messages={"info": "charging soon"},
        position_initialized=True,
        maps=[{"map_id": "map", "map_version": "1", "map_status": "ENABLED", "map_description": None}],
        zone_sets=[{"map_id": "map", "zone_set_id": "floor1-v1", "zone_set_status": "ENABLED"}],
        supported_zones=["RELEASE", "BLOCKED"],
        zone_access={"held": [{"map_id": "map", "zone_id": "aisle"}], "waiting": []},
    )

    response = api.get("/robot/carter01")

    assert response.status_code == 200
    assert response.json()["status"] == {
        "pose": {
            "x": 4.0,
            "y": 5.0,
            "theta": 1.5,
            "map_id": "map",
            "allowedDeviationXY": 0.1,
            "allowedDeviationTheta": 0.0,
        },
        "position_initialized": True,
        "software_version": {"os": "linux", "app": ""},
        "hardware_version": {"manufacturer": "RobotCompany", "serial_number": "carter01"},
        "factsheet": {"agv_class": "FORKLIFT", "speed_max": 1.5, "supported_zones": ["RELEASE", "BLOCKED"]},
        "online": True,
        "battery_level": 42.0,
        "state": "ON_TASK",
        "state_since": "2026-11-28T04:30:00Z",
        "operating_mode": "AUTOMATIC",
        "info_messages": {"info": "charging soon"},
        "errors": {},
        "maps": [{"map_id": "map", "map_version": "1", "map_status": "ENABLED", "map_description": None}],
        "zone_sets": [{"map_id": "map", "zone_set_id": "floor1-v1", "zone_set_status": "ENABLED"}],
        "zone_access": {"held": [{"map_id": "map", "zone_id": "aisle"}], "waiting": []},
        "charge_requested": False,
        "charging_waiting_reason": None,
    }


def test_missing_robot_is_400_with_the_reference_message(api):
    response = api.get("/robot/carter99")

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "robot" with name "carter99"'}


def test_a_robot_pending_delete_is_still_returned(api):
    RobotFactory(name="carter01", lifecycle="PENDING_DELETE")

    assert api.get("/robot/carter01").json()["lifecycle"] == "PENDING_DELETE"


def test_trailing_slash_is_not_a_route(api):
    RobotFactory(name="carter01")

    assert api.get("/robot/carter01/").status_code == 404
