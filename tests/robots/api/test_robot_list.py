"""GET /robot and its filters."""

import pytest

from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db


def names(response) -> list[str]:
    assert response.status_code == 200, response.json()
    return [robot["name"] for robot in response.json()]


@pytest.fixture
def fleet() -> None:
    RobotFactory(name="idle_full", state="IDLE", online=True, battery_level=90.0, agv_class="CARRIER")
    RobotFactory(name="idle_low", state="IDLE", online=True, battery_level=15.0, agv_class="CARRIER")
    RobotFactory(name="busy", state="ON_TASK", online=True, battery_level=60.0, agv_class="FORKLIFT")
    RobotFactory(
        name="lost",
        state="IDLE",
        online=False,
        battery_level=50.0,
        agv_class="MANIPULATOR",
        position_initialized=True,
    )
    RobotFactory(name="charging", state="CHARGING", online=True, battery_level=30.0, agv_class="TUGGER")


def test_lists_every_robot_by_name(api, fleet):
    assert names(api.get("/robot")) == ["busy", "charging", "idle_full", "idle_low", "lost"]


def test_an_empty_fleet_is_an_empty_list(api):
    assert api.get("/robot").json() == []


def test_robots_pending_delete_are_listed(api):
    RobotFactory(name="leaving", lifecycle="PENDING_DELETE")

    assert [robot["lifecycle"] for robot in api.get("/robot").json()] == ["PENDING_DELETE"]


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ("min_battery=50", ["busy", "idle_full", "lost"]),
        ("max_battery=30", ["charging", "idle_low"]),
        ("min_battery=30&max_battery=60", ["busy", "charging", "lost"]),
        ("min_battery=60.5", ["idle_full"]),
        ("state=IDLE", ["idle_full", "idle_low", "lost"]),
        ("state=CHARGING", ["charging"]),
        ("state=TELEOP", []),
        ("online=true", ["busy", "charging", "idle_full", "idle_low"]),
        ("online=false", ["lost"]),
        ("online=False", ["lost"]),
        ("online=1", ["busy", "charging", "idle_full", "idle_low"]),
        ("position_initialized=true", ["lost"]),
        ("names=busy", ["busy"]),
        ("names=busy&names=lost", ["busy", "lost"]),
        ("names=busy&names=nobody", ["busy"]),
        ("robot_type=FORKLIFT", ["busy"]),
        ("robot_type=MANIPULATOR", ["lost"]),
        ("robot_type=HUMANOID", []),
        ("robot_type=ARM", ["busy"]),
        ("robot_type=AMR", ["idle_full", "idle_low"]),
        ("state=IDLE&online=true&min_battery=50", ["idle_full"]),
        ("state=IDLE&online=true&max_battery=50", ["idle_low"]),
        ("names=idle_full&names=idle_low&names=busy&robot_type=AMR&min_battery=20", ["idle_full"]),
        ("online=true&robot_type=TUGGER&state=CHARGING", ["charging"]),
        ("unknown_parameter=1", ["busy", "charging", "idle_full", "idle_low", "lost"]),
    ],
)
def test_filters(api, fleet, query, expected):
    assert names(api.get(f"/robot?{query}")) == expected


def test_the_reference_sql_injection_example_matches_no_robot(api, fleet):
    assert names(api.get("/robot", {"names": "zzz') OR ('1'='1"})) == []


def test_injection_in_other_filters_is_an_invalid_value(api, fleet):
    response = api.get("/robot", {"state": "IDLE' OR '1'='1"})

    assert response.status_code == 400


@pytest.mark.parametrize(
    ("query", "field"),
    [
        ("min_battery=full", "min_battery"),
        ("max_battery=NaN", "max_battery"),
        ("min_battery=inf", "min_battery"),
        ("state=FLYING", "state"),
        ("state=idle", "state"),
        ("online=maybe", "online"),
        ("position_initialized=2", "position_initialized"),
        ("robot_type=ROCKET", "robot_type"),
    ],
)
def test_invalid_filter_values_are_400_located_in_the_query(api, fleet, query, field):
    response = api.get(f"/robot?{query}")

    assert response.status_code == 400
    [error] = response.json()["detail"]
    assert error["loc"] == ["query", field]
    assert error["msg"]


def test_every_invalid_filter_is_reported(api):
    response = api.get("/robot?min_battery=x&online=perhaps")

    assert sorted(error["loc"][1] for error in response.json()["detail"]) == ["min_battery", "online"]
