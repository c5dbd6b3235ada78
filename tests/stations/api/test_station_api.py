"""GET/POST /station, GET/PUT/DELETE /station/{name}: the shape, naming, defaults, filters, every validation
rule, and the write records (real PostgreSQL)."""

import json
import re
from pathlib import Path

import pytest
from django.utils import timezone

from access.models import WriteRecord
from robots.models import Robot
from stations.models import MAX_CAPACITY, Station
from tests.factories import CAN_CHARGE, RobotFactory

pytestmark = pytest.mark.django_db

CHARGER = {
    "name": "charger01",
    "kind": "CHARGER",
    "pose": {"x": 1.0, "y": 2.0, "theta": 0.5, "map_id": "map"},
}
GENERATED_NAME = re.compile(r"[a-z2-7]{26}")
README = (Path(__file__).resolve().parents[3] / "README.md").read_text()


def test_a_charger_is_created_with_the_shape_of_robots_and_missions(api):
    response = api.post("/station", CHARGER, format="json")

    assert response.status_code == 200, response.content
    assert response.json() == {
        "kind": "CHARGER",
        "pose": {"x": 1.0, "y": 2.0, "theta": 0.5, "map_id": "map"},
        "robot_types": [],
        "capacity": 1,
        "name": "charger01",
        "status": {"reservations": []},
        "lifecycle": "ALIVE",
    }
    assert api.get("/station/charger01").json() == response.json()
    assert WriteRecord.objects.filter(action="station_create", object_name="charger01").exists()


def test_a_station_without_a_name_gets_a_generated_one_or_its_prefix(api):
    unnamed = api.post("/station", {"kind": "PARKING", "pose": {}}, format="json").json()
    prefixed = api.post("/station", {"prefix": "park", "kind": "PARKING", "pose": {}}, format="json").json()

    assert GENERATED_NAME.fullmatch(unnamed["name"])
    assert prefixed["name"].startswith("park-")
    assert unnamed["pose"] == {"x": 0.0, "y": 0.0, "theta": 0.0, "map_id": ""}


def test_a_duplicate_name_is_the_references_error(api):
    api.post("/station", CHARGER, format="json")

    response = api.post("/station", CHARGER, format="json")

    assert (response.status_code, response.json()) == (
        400,
        {"detail": "Object station with name charger01 already exists"},
    )


@pytest.mark.parametrize(
    ("body", "loc", "type"),
    [
        ({"pose": {}}, ["body", "kind"], "required"),
        ({"kind": "DOCK", "pose": {}}, ["body", "kind"], "invalid_choice"),
        ({"kind": "CHARGER"}, ["body", "pose"], "required"),
        ({**CHARGER, "capacity": 0}, ["body", "capacity"], "min_value"),
        ({**CHARGER, "capacity": MAX_CAPACITY + 1}, ["body", "capacity"], "max_value"),
        ({**CHARGER, "capacity": "2"}, ["body", "capacity"], "invalid"),
        ({**CHARGER, "robot_types": ["SPACESHIP"]}, ["body", "robot_types", 0], "invalid_choice"),
        ({**CHARGER, "robot_types": ["CARRIER", "CARRIER"]}, ["body", "robot_types"], "duplicate"),
        ({**CHARGER, "pose": {"x": "1"}}, ["body", "pose", "x"], "invalid"),
        (
            {**CHARGER, "pose": {"allowedDeviationXY": 1}},
            ["body", "pose", "allowedDeviationXY"],
            "extra_forbidden",
        ),
        ({**CHARGER, "colour": "red"}, ["body", "colour"], "extra_forbidden"),
        ({**CHARGER, "name": "a b"}, ["body", "name"], "invalid_name"),
    ],
)
def test_invalid_bodies_are_a_400_that_says_where(api, body, loc, type):
    response = api.post("/station", body, format="json")

    assert response.status_code == 400
    assert {"loc": loc, "type": type} in [
        {"loc": error["loc"], "type": error["type"]} for error in response.json()["detail"]
    ], response.json()
    assert not Station.objects.exists()


def test_status_cannot_be_written(api):
    response = api.post("/station", {**CHARGER, "status": {"reservations": ["r1"]}}, format="json")

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"


def test_put_replaces_the_whole_spec(api):
    api.post("/station", {**CHARGER, "robot_types": ["CARRIER"], "capacity": 3}, format="json")

    response = api.put("/station/charger01", {"kind": "PARKING", "pose": {"x": 9.0}}, format="json")

    assert response.status_code == 200, response.content
    assert {key: response.json()[key] for key in ("kind", "pose", "robot_types", "capacity")} == {
        "kind": "PARKING",
        "pose": {"x": 9.0, "y": 0.0, "theta": 0.0, "map_id": ""},
        "robot_types": [],
        "capacity": 1,
    }
    assert WriteRecord.objects.filter(action="station_update", object_name="charger01").exists()


def test_a_held_station_keeps_its_capacity_and_is_not_deleted(api):
    api.post("/station", {**CHARGER, "capacity": 2}, format="json")
    Station.objects.filter(name="charger01").update(reservations=["r1", "r2"])

    lowered = api.put("/station/charger01", {"kind": "CHARGER", "pose": {}, "capacity": 1}, format="json")
    deleted = api.delete("/station/charger01")

    assert (lowered.status_code, lowered.json()["error_code"]) == (400, "USAGE")
    assert "r1, r2" in lowered.json()["message"]
    assert (deleted.status_code, deleted.json()["error_code"]) == (400, "USAGE")
    assert Station.objects.get(name="charger01").capacity == 2


def test_delete_removes_the_station(api):
    api.post("/station", CHARGER, format="json")

    response = api.delete("/station/charger01")

    assert (response.status_code, response.json()) == (200, {"detail": "charger01 is DELETED"})
    assert not Station.objects.exists()
    assert WriteRecord.objects.filter(action="station_delete", object_name="charger01").exists()


def test_a_missing_station_is_the_references_error(api):
    assert api.get("/station/nope").json() == {"detail": 'Did not find "station" with name "nope"'}
    missing_put = api.put("/station/nope", {"kind": "CHARGER", "pose": {}}, format="json")
    assert missing_put.json() == {"detail": "Could not find object nope"}
    assert api.delete("/station/nope").json() == {"detail": "Could not find object nope"}


def test_the_list_filters_by_kind_map_robot_type_and_names(api):
    api.post("/station", CHARGER, format="json")
    api.post("/station", {**CHARGER, "name": "c2", "robot_types": ["FORKLIFT"]}, format="json")
    api.post("/station", {"name": "p1", "kind": "PARKING", "pose": {"map_id": "yard"}}, format="json")

    def names(query: str) -> list[str]:
        response = api.get("/station" + query)
        assert response.status_code == 200, response.content
        return [station["name"] for station in response.json()]

    assert names("") == ["c2", "charger01", "p1"]
    assert names("?kind=CHARGER") == ["c2", "charger01"]
    assert names("?map_id=yard") == ["p1"]
    assert names("?robot_type=CARRIER") == ["charger01", "p1"]
    assert names("?robot_type=FORKLIFT") == ["c2", "charger01", "p1"]
    assert names("?names=p1&names=c2") == ["c2", "p1"]
    assert api.get("/station?kind=DOCK").status_code == 400
    assert api.get("/station?kind=").status_code == 400


def test_a_map_id_as_long_as_any_text_is_stored(api, settings):
    long_map = "m" * settings.API_MAX_TEXT_LENGTH

    response = api.post("/station", {**CHARGER, "pose": {"map_id": long_map}}, format="json")

    assert response.status_code == 200, response.content
    assert api.get(f"/station?map_id={long_map}").json()[0]["pose"]["map_id"] == long_map


def readme_charging_commands() -> list[tuple[str, str, dict | None]]:
    """The curl commands of README.md's "Stations: charging and parking" example: (method, path, body)."""
    section = README.split("### Stations: charging and parking", 1)[1].split("\n### ", 1)[0]
    block = section.split("```sh\n", 1)[1].split("```", 1)[0].replace("\\\n", " ")
    commands = []
    for line in block.splitlines():
        method = re.search(r"-X (\w+)", line)
        path = re.search(r"'?localhost:5000(/[^\s']*)", line)
        body = re.search(r"-d '([^']*)'", line)
        assert path, line
        commands.append((method[1] if method else "GET", path[1], json.loads(body[1]) if body else None))
    return commands


def test_the_readme_charging_example_is_accepted(api):
    """The README's example, as a new user runs it under `make run`: carter01 created as "Try it" does,
    online with the simulator's factsheet (which lists startCharging)."""
    RobotFactory(name="carter01", online=True, factsheet=CAN_CHARGE, last_state_at=timezone.now())

    commands = readme_charging_commands()

    assert [method for method, _, _ in commands] == ["PUT", "POST", "POST", "GET", "GET"]
    for method, path, body in commands:
        if "/watch" in path:
            continue  # a stream: tests/changes
        response = api.generic(method, path, json.dumps(body) if body else "", "application/json")
        assert response.status_code == 200, (method, path, response.content)
    robot = Robot.objects.get(name="carter01")
    assert (robot.battery_recommended_minimum, robot.battery_recommended_maximum) == (30.0, 95.0)
    assert robot.charge_requested and Station.objects.filter(name="charger01", kind="CHARGER").exists()
