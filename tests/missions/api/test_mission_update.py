"""POST /mission/{name}/update: new waypoints for route nodes."""

import pytest

from missions.models import Mission
from tests.factories import MissionFactory, route_node

pytestmark = pytest.mark.django_db

UPDATE = {"goto": {"waypoints": [{"x": 7, "y": 8, "map_id": "map"}]}}
UPDATE_WITH_DEFAULTS = {
    "goto": {
        "waypoints": [
            {
                "x": 7.0,
                "y": 8.0,
                "theta": 0.0,
                "map_id": "map",
                "allowedDeviationXY": 0.1,
                "allowedDeviationTheta": 0.0,
            }
        ]
    }
}


def two_routes(**traits) -> Mission:
    """A mission whose first route `done` is COMPLETED when it runs, and whose second route `goto` is not."""
    mission = MissionFactory(
        name="m1", robot="carter01", mission_tree=[route_node("done"), route_node("goto")], **traits
    )
    if mission.state == "RUNNING":
        mission.node_status["done"]["state"] = "COMPLETED"
        mission.node_status["goto"]["state"] = "RUNNING"
        mission.save()
    return mission


def test_a_pending_mission_takes_the_update(api, woken):
    two_routes()

    response = api.post("/mission/m1/update", UPDATE)

    assert response.status_code == 200
    assert response.json() == UPDATE_WITH_DEFAULTS
    assert Mission.objects.get(name="m1").update_nodes == UPDATE_WITH_DEFAULTS
    assert api.get("/mission/m1").json()["update_nodes"] == UPDATE_WITH_DEFAULTS
    assert woken == ["carter01"]


def test_the_running_node_of_a_running_mission_can_be_updated(api):
    two_routes(running=True)

    response = api.post("/mission/m1/update", UPDATE)

    assert response.status_code == 200
    assert Mission.objects.get(name="m1").update_nodes == UPDATE_WITH_DEFAULTS


def test_the_stored_tree_is_not_rewritten(api):
    two_routes()

    api.post("/mission/m1/update", UPDATE)

    assert Mission.objects.get(name="m1").mission_tree == [route_node("done"), route_node("goto")]


def test_updates_are_merged_by_node_name(api):
    two_routes()
    first = {"done": {"waypoints": [{"x": 1}]}, "goto": {"waypoints": [{"x": 2}]}}
    api.post("/mission/m1/update", first)

    api.post("/mission/m1/update", {"goto": {"waypoints": [{"x": 3}]}})

    update_nodes = Mission.objects.get(name="m1").update_nodes
    assert [update_nodes[name]["waypoints"][0]["x"] for name in ("done", "goto")] == [1.0, 3.0]


def test_a_finished_node_of_a_running_mission_cannot_be_updated(api, woken):
    two_routes(running=True)

    response = api.post("/mission/m1/update", {"done": {"waypoints": [{"x": 1}]}})

    assert response.status_code == 400
    assert response.json() == {
        "message": "Mission node done is finished with status COMPLETED.",
        "error_code": "USAGE",
    }
    assert Mission.objects.get(name="m1").update_nodes is None
    assert woken == []


@pytest.mark.parametrize("trait", ["completed", "failed", "canceled"])
def test_a_finished_mission_cannot_be_updated(api, trait):
    two_routes(**{trait: True})

    response = api.post("/mission/m1/update", UPDATE)

    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"
    assert "is finished with status" in response.json()["message"]


def test_only_route_nodes_can_be_updated(api):
    MissionFactory(
        name="m1",
        mission_tree=[{"name": "s", "parent": "root", "sequence": {}}, route_node("goto", parent="s")],
    )

    response = api.post("/mission/m1/update", {"s": {"waypoints": [{"x": 1}]}})

    assert response.json() == {
        "message": "Node s of mission m1 is a sequence node; only routes can be updated.",
        "error_code": "USAGE",
    }


@pytest.mark.parametrize("node", ["nowhere", "root"])
def test_the_node_must_exist(api, node):
    two_routes()

    response = api.post("/mission/m1/update", {node: {"waypoints": [{"x": 1}]}})

    assert response.json() == {"message": f"Node {node} does not exist in mission m1", "error_code": "USAGE"}


def test_one_bad_node_refuses_the_whole_update(api):
    two_routes()

    api.post("/mission/m1/update", {"goto": {"waypoints": [{"x": 1}]}, "nowhere": {"waypoints": [{"x": 1}]}})

    assert Mission.objects.get(name="m1").update_nodes is None


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"goto": {"waypoints": []}}, ["body", "goto", "waypoints"]),
        ({"goto": {}}, ["body", "goto", "waypoints"]),
        ({"goto": {"waypoints": [{"x": "far"}]}}, ["body", "goto", "waypoints", 0, "x"]),
        ({"goto": {"waypoints": [{"x": 1}], "speed": 1}}, ["body", "goto", "speed"]),
        ({"goto": [1]}, ["body", "goto"]),
        ([{"goto": {}}], ["body"]),
    ],
)
def test_invalid_bodies_are_400(api, body, loc):
    two_routes()

    response = api.post("/mission/m1/update", body)

    assert response.status_code == 400
    assert loc in [error["loc"] for error in response.json()["detail"]]


def test_missing_mission_is_400_with_the_reference_message(api):
    response = api.post("/mission/nothing/update", UPDATE)

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "mission" with name "nothing"'}
