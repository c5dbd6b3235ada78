"""POST /mission without a robot, priority and robot_selector; GET /mission?unbound= (issue 41)."""

import pytest

from dispatch.assignment import NOT_YET_ASSIGNED
from missions.models import Mission
from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db

ROUTE = {"route": {"waypoints": [{"x": 1, "y": 2}]}}


def body(**spec) -> dict:
    return {"mission_tree": [ROUTE], **spec}


def schema_error_locs(response) -> list[list]:
    assert response.status_code == 400, response.json()
    return [error["loc"] for error in response.json()["detail"]]


@pytest.mark.parametrize("spec", [{}, {"robot": None}])
def test_a_mission_without_a_robot_is_unbound_and_pending(api, woken, spec):
    response = api.post("/mission", body(name="m1", **spec))

    assert response.status_code == 200, response.json()
    created = response.json()
    assert (created["robot"], created["priority"], created["robot_selector"]) == (None, 0, None)
    assert created["status"]["state"] == "PENDING"
    assert created["status"]["assignment"] == []
    assert created["status"]["waiting_reason"] == NOT_YET_ASSIGNED  # says why from the start
    assert Mission.objects.get(name="m1").robot is None
    assert woken == []  # no robot to step: assignment is asked for instead


def test_a_selector_and_priority_are_stored_normalized(api, woken):
    response = api.post(
        "/mission", body(name="m1", priority=-1000, robot_selector={"labels": ["forklift", "cold"]})
    )

    assert response.status_code == 200, response.json()
    assert response.json()["priority"] == -1000
    assert response.json()["robot_selector"] == {
        "labels": ["forklift", "cold"],
        "robot_types": [],
        "action_types": [],
    }
    assert api.get("/mission/m1").json()["robot_selector"]["labels"] == ["forklift", "cold"]


def test_a_named_robots_mission_takes_a_priority(api, woken):
    response = api.post("/mission", body(robot="carter01", priority=1000))

    assert (response.json()["robot"], response.json()["priority"]) == ("carter01", 1000)
    assert woken == ["carter01"]


@pytest.mark.parametrize(
    ("spec", "loc"),
    [
        ({"priority": 1001}, ["body", "priority"]),
        ({"priority": -1001}, ["body", "priority"]),
        ({"priority": 1.5}, ["body", "priority"]),
        ({"priority": "high"}, ["body", "priority"]),
        ({"priority": True}, ["body", "priority"]),
        ({"robot_selector": {"colour": ["red"]}}, ["body", "robot_selector", "colour"]),
        ({"robot_selector": {"labels": "forklift"}}, ["body", "robot_selector", "labels"]),
        ({"robot_selector": {"labels": [1]}}, ["body", "robot_selector", "labels", 0]),
        ({"robot_selector": {"robot_types": [None]}}, ["body", "robot_selector", "robot_types", 0]),
        ({"robot_selector": {"action_types": ["a"] * 101}}, ["body", "robot_selector", "action_types"]),
        ({"robot_selector": ["forklift"]}, ["body", "robot_selector"]),
        ({"robot": "carter01", "robot_selector": {"labels": ["x"]}}, ["body", "robot_selector"]),
    ],
)
def test_bad_priorities_and_selectors_are_schema_errors(api, spec, loc):
    assert loc in schema_error_locs(api.post("/mission", body(**spec)))
    assert not Mission.objects.exists()


def test_a_selector_of_null_beside_a_robot_is_accepted(api, woken):
    response = api.post("/mission", body(robot="carter01", robot_selector=None))

    assert response.status_code == 200, response.json()


def test_the_unbound_filter_lists_missions_without_a_robot(api):
    MissionFactory(name="named", robot="carter01")
    MissionFactory(name="free", robot=None)

    assert [m["name"] for m in api.get("/mission?unbound=true").json()] == ["free"]
    assert [m["name"] for m in api.get("/mission?unbound=false").json()] == ["named"]
    assert [m["name"] for m in api.get("/mission?robot=carter01").json()] == ["named"]
    assert api.get("/mission?unbound=maybe").status_code == 400
