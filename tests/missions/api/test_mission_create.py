"""POST /mission: the README missions, the stored (normalized) tree, naming, and every validation rule."""

import copy
import re

import pytest

from missions.models import Mission
from robots import livestate
from tests.factories import MissionFactory
from tests.private_redis import PrivateRedis, live_state_in
from tests.readme import README_MISSIONS
from tests.waiting import wait_for
from workers import step_requests

pytestmark = pytest.mark.django_db

ROUTE_TREE = [{"route": {"waypoints": [{"x": 1.0, "y": 2.0, "theta": 0.0, "map_id": "map"}]}}]

KINDS = ("selector", "sequence", "route", "move", "action", "notify", "constant")
GENERATED_NAME = re.compile(r"[a-z2-7]{26}")


def waypoint(x: float, y: float) -> dict:
    return {
        "x": x,
        "y": y,
        "theta": 0.0,
        "map_id": "",
        "allowedDeviationXY": 0.1,
        "allowedDeviationTheta": 0.0,
    }


def mission(*mission_tree: dict, **spec) -> dict:
    return {"robot": "carter01", "mission_tree": list(mission_tree), **spec}


def route(**node) -> dict:
    return {"route": {"waypoints": [{"x": 1, "y": 2}]}, **node}


def as_returned(node: dict) -> dict:
    """A stored node as the API returns it: the kinds it does not have are null."""
    return {"name": node["name"], "parent": node["parent"], **dict.fromkeys(KINDS), **node}


def usage_error(response) -> str:
    assert response.status_code == 400, response.json()
    assert response.json()["error_code"] == "USAGE"
    return response.json()["message"]


def schema_error_locs(response) -> list[list]:
    assert response.status_code == 400, response.json()
    return [error["loc"] for error in response.json()["detail"]]


@pytest.mark.parametrize("name", sorted(README_MISSIONS))
def test_readme_missions_are_accepted_verbatim(api, woken, name):
    body = copy.deepcopy(README_MISSIONS[name])

    response = api.post("/mission", body)

    assert response.status_code == 200, response.json()
    created = response.json()
    assert created["name"] == name
    assert created["robot"] == "carter01"
    assert [node["name"] for node in created["mission_tree"]] == [
        node["name"] for node in body["mission_tree"]
    ]
    assert [node["parent"] for node in created["mission_tree"]] == [
        node["parent"] for node in body["mission_tree"]
    ]
    assert created["timeout"] == 300.0
    assert created["deadline"].startswith(body["deadline"][:19])
    assert created["needs_canceled"] is False
    assert created["status"]["state"] == "PENDING"
    assert set(created["status"]["node_status"]) == {"root", *(node["name"] for node in body["mission_tree"])}
    assert woken == ["carter01"]


def test_the_complex_readme_mission_is_stored_normalized(api):
    api.post("/mission", README_MISSIONS["complex_mission_example"])

    stored = Mission.objects.get(name="complex_mission_example")
    assert stored.mission_tree[1] == {
        "name": "pickup_book",
        "parent": "root",
        "action": {"action_type": "dummy_action", "action_parameters": {"should_fail": 0, "time": 1}},
    }
    assert stored.mission_tree[2] == {"name": "route_fallback", "parent": "root", "selector": {}}
    assert stored.mission_tree[3]["route"]["waypoints"][1] == {
        "x": 0.8,
        "y": 1.8,
        "theta": 0.0,
        "map_id": "map",
        "allowedDeviationXY": 0.1,
        "allowedDeviationTheta": 0.0,
    }


def test_a_new_mission_has_every_node_pending_and_an_empty_status(api):
    response = api.post(
        "/mission", mission(route(name="a"), {"name": "s", "sequence": {}}, route(parent="s"))
    )

    assert response.json()["status"] == {
        "state": "PENDING",
        "current_node": 0,
        "node_status": {name: {"state": "PENDING", "error_msg": None} for name in ("root", "a", "s", "2")},
        "task_status": {},
        "start_timestamp": None,
        "end_timestamp": None,
        "failure_reason": None,
        "failure_category": None,
        "waiting_reason": None,
        "assignment": [],
    }
    assert response.json()["lifecycle"] == "ALIVE"


def test_unnamed_nodes_are_named_by_their_index_and_defaults_are_applied(api):
    response = api.post(
        "/mission",
        mission(
            {"route": {"waypoints": [{"x": 1, "y": 2}]}},
            {"name": "pick", "action": {"action_type": "pick"}},
            {"notify": {"url": "http://localhost:8000/done"}},
            {"constant": {}},
            {"move": {"rotation": 1.57}},
        ),
    )

    assert response.status_code == 200, response.json()
    stored = [
        {"name": "0", "parent": "root", "route": {"waypoints": [waypoint(1, 2)]}},
        {"name": "pick", "parent": "root", "action": {"action_type": "pick", "action_parameters": {}}},
        {
            "name": "2",
            "parent": "root",
            "notify": {"url": "http://localhost:8000/done", "json_data": {}, "timeout": 30},
        },
        {"name": "3", "parent": "root", "constant": {"success": True}},
        {"name": "4", "parent": "root", "move": {"distance": None, "rotation": 1.57}},
    ]
    assert Mission.objects.get(name=response.json()["name"]).mission_tree == stored
    assert response.json()["mission_tree"] == [as_returned(node) for node in stored]


def test_notify_data_is_stored_as_given_even_beyond_64_bit_integers(api):
    json_data = {"order": 2**70, "ratio": 0.5, "tags": ["a", None, True], "nested": {"é": "ü"}}

    response = api.post(
        "/mission", mission({"notify": {"url": "http://localhost:8000/done", "json_data": json_data}})
    )

    assert response.status_code == 200, response.json()
    stored = Mission.objects.get(name=response.json()["name"]).mission_tree[0]["notify"]["json_data"]
    assert stored == json_data


def test_spec_defaults(api):
    body = api.post("/mission", mission(route())).json()

    assert (body["timeout"], body["deadline"], body["needs_canceled"], body["update_nodes"]) == (
        300.0,
        None,
        False,
        None,
    )
    assert GENERATED_NAME.fullmatch(body["name"])


def test_prefix_gives_prefix_dash_generated_id(api):
    name = api.post("/mission", mission(route(), prefix="delivery")).json()["name"]

    prefix, generated = name.split("-")
    assert prefix == "delivery"
    assert GENERATED_NAME.fullmatch(generated)


def test_name_and_prefix_together_are_a_usage_error(api):
    response = api.post("/mission", mission(route(), name="m1", prefix="m"))

    assert usage_error(response) == 'Cannot have both "name" and "prefix"'


def test_duplicate_name_is_refused_with_the_reference_message(api):
    MissionFactory(name="m1")

    response = api.post("/mission", mission(route(), name="m1"))

    assert response.status_code == 400
    assert response.json() == {"detail": "Object mission with name m1 already exists"}


def test_a_mission_for_a_robot_that_does_not_exist_yet_is_accepted(api):
    response = api.post("/mission", mission(route(), robot="future_robot"))

    assert response.status_code == 200
    assert response.json()["robot"] == "future_robot"


def test_missions_are_queued_in_submission_order(api):
    for name in ("m3", "m1", "m2"):
        api.post("/mission", mission(route(), name=name))

    assert [body["name"] for body in api.get("/mission").json()] == ["m3", "m1", "m2"]


def test_explicit_null_kinds_count_as_absent(api):
    node = {"name": "go", **dict.fromkeys(KINDS), "route": {"waypoints": [{"x": 1}]}}

    response = api.post("/mission", mission(node))

    assert response.status_code == 200, response.json()
    assert Mission.objects.get(name=response.json()["name"]).mission_tree[0] == {
        "name": "go",
        "parent": "root",
        "route": {"waypoints": [waypoint(1, 0)]},
    }


def test_a_mission_returned_by_the_api_can_be_submitted_again(api):
    first = api.post("/mission", README_MISSIONS["complex_mission_example"]).json()
    spec = {key: first[key] for key in ("robot", "mission_tree", "timeout", "deadline", "needs_canceled")}

    response = api.post("/mission", {**spec, "name": "again"})

    assert response.status_code == 200, response.json()
    assert response.json()["mission_tree"] == first["mission_tree"]


def test_needs_canceled_on_create_gives_a_canceled_mission(api):
    response = api.post("/mission", mission(route(name="go"), needs_canceled=True))

    status = response.json()["status"]
    assert status["state"] == "CANCELED"
    assert status["failure_category"] == "CANCELED"
    assert status["end_timestamp"] is not None
    assert status["node_status"]["root"]["state"] == "CANCELED"
    assert status["node_status"]["go"]["state"] == "PENDING"


def test_update_nodes_on_create_are_stored_with_defaults(api):
    response = api.post(
        "/mission", mission(route(name="go"), update_nodes={"go": {"waypoints": [{"x": 5, "y": 6}]}})
    )

    assert response.json()["update_nodes"] == {"go": {"waypoints": [waypoint(5, 6)]}}


def test_update_nodes_on_create_must_name_route_nodes(api):
    response = api.post(
        "/mission",
        mission({"name": "s", "sequence": {}}, update_nodes={"s": {"waypoints": [{"x": 5}]}}),
    )

    assert "only routes" in usage_error(response)


def test_a_far_deadline_with_an_offset_is_kept(api):
    response = api.post("/mission", mission(route(), deadline="2030-01-02T03:04:05+02:00"))

    assert response.json()["deadline"] == "2030-01-02T01:04:05Z"


# --- mission tree rules: USAGE errors ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("mission_tree", "message_part"),
    [
        ([{"name": "a"}], "Exactly one"),
        ([{"name": "a", "route": {"waypoints": [{}]}, "action": {"action_type": "x"}}], "Exactly one"),
        ([{"name": "a", "selector": {}, "sequence": {}}], "Exactly one"),
        ([route(name="a"), route(name="a")], "repeated"),
        ([route(name="root")], "reserved"),
        ([route(name="a", parent="nowhere")], "parent nowhere"),
        ([route(name="a", parent="s"), {"name": "s", "sequence": {}}], "parent s"),
        ([route(name="a"), route(name="b", parent="a")], "cannot have children"),
        ([{"name": "c", "constant": {}}, route(parent="c")], "cannot have children"),
        ([{"name": "self", "sequence": {}, "parent": "self"}], "parent self"),
    ],
)
def test_tree_rules_are_usage_errors(api, mission_tree, message_part):
    response = api.post("/mission", mission(*mission_tree))

    assert message_part in usage_error(response)
    assert not Mission.objects.exists()


def test_a_duplicate_names_message_names_the_node(api):
    response = api.post("/mission", mission(route(name="goto"), route(name="goto")))

    assert usage_error(response) == "MissionNode name goto is repeated. All MissionNode names must be unique."


def test_an_unnamed_node_cannot_take_a_name_used_by_an_index(api):
    response = api.post("/mission", mission(route(), route(name="0")))

    assert "repeated" in usage_error(response)


def test_status_in_the_body_is_a_usage_error(api):
    response = api.post("/mission", mission(route(), status={"state": "COMPLETED"}))

    assert "status" in usage_error(response)


# --- schema errors ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("body", "loc"),
    [
        ({"robot": "carter01"}, ["body", "mission_tree"]),
        (mission(), ["body", "mission_tree"]),
        (mission(route(), colour="red"), ["body", "colour"]),
        (mission(route(), timeout=0), ["body", "timeout"]),
        (mission(route(), timeout=-1), ["body", "timeout"]),
        (mission(route(), timeout="long"), ["body", "timeout"]),
        (mission(route(), deadline="tomorrow"), ["body", "deadline"]),
        (mission(route(), robot="carter 01"), ["body", "robot"]),
        (mission(route(), name="m/1"), ["body", "name"]),
        (mission(route(), name="m" * 101), ["body", "name"]),
        (mission(route(), prefix="p" * 74), ["body", "prefix"]),
        (mission(route(), needs_canceled="maybe"), ["body", "needs_canceled"]),
        (mission(route(), update_nodes={"0": {"waypoints": []}}), ["body", "update_nodes", "0", "waypoints"]),
        (mission(route(tag=1)), ["body", "mission_tree", 0, "tag"]),
        (mission(route(name="a b")), ["body", "mission_tree", 0, "name"]),
        (mission(route(name="n" * 101)), ["body", "mission_tree", 0, "name"]),
        (mission(route(), {"route": {"waypoints": []}}), ["body", "mission_tree", 1, "route", "waypoints"]),
        (mission({"route": {}}), ["body", "mission_tree", 0, "route", "waypoints"]),
        (
            mission({"route": {"waypoints": [{"x": "far"}]}}),
            ["body", "mission_tree", 0, "route", "waypoints", 0, "x"],
        ),
        (
            mission({"route": {"waypoints": [{"x": 1, "z": 2}]}}),
            ["body", "mission_tree", 0, "route", "waypoints", 0, "z"],
        ),
        (
            mission({"route": {"waypoints": [{"allowedDeviationXY": -1}]}}),
            ["body", "mission_tree", 0, "route", "waypoints", 0, "allowedDeviationXY"],
        ),
        (mission({"route": {"waypoints": [{}], "speed": 2}}), ["body", "mission_tree", 0, "route", "speed"]),
        (mission({"move": {"distance": 1, "rotation": 1}}), ["body", "mission_tree", 0, "move"]),
        (mission({"move": {}}), ["body", "mission_tree", 0, "move"]),
        (mission({"move": {"distance": None, "rotation": None}}), ["body", "mission_tree", 0, "move"]),
        (mission({"move": {"distance": "one"}}), ["body", "mission_tree", 0, "move", "distance"]),
        (mission({"action": {}}), ["body", "mission_tree", 0, "action", "action_type"]),
        (
            mission({"action": {"action_type": "pick", "action_parameters": [1]}}),
            ["body", "mission_tree", 0, "action", "action_parameters"],
        ),
        (
            mission({"action": {"action_type": "pick", "params": {}}}),
            ["body", "mission_tree", 0, "action", "params"],
        ),
        (mission({"notify": {}}), ["body", "mission_tree", 0, "notify", "url"]),
        (mission({"notify": {"url": "localhost/done"}}), ["body", "mission_tree", 0, "notify", "url"]),
        (mission({"notify": {"url": "ftp://host/done"}}), ["body", "mission_tree", 0, "notify", "url"]),
        (
            mission({"notify": {"url": "http://h/", "timeout": 0}}),
            ["body", "mission_tree", 0, "notify", "timeout"],
        ),
        (
            mission({"notify": {"url": "http://h/", "timeout": 1.5}}),
            ["body", "mission_tree", 0, "notify", "timeout"],
        ),
        (
            mission({"notify": {"url": "http://h/", "json_data": 3}}),
            ["body", "mission_tree", 0, "notify", "json_data"],
        ),
        (mission({"constant": {"success": "yes!"}}), ["body", "mission_tree", 0, "constant", "success"]),
        (mission({"constant": {"value": True}}), ["body", "mission_tree", 0, "constant", "value"]),
        (mission({"sequence": {"memory": True}}), ["body", "mission_tree", 0, "sequence", "memory"]),
        (mission({"selector": []}), ["body", "mission_tree", 0, "selector"]),
        (mission("route"), ["body", "mission_tree", 0]),
    ],
)
def test_invalid_bodies_are_400_with_fastapi_shaped_errors(api, body, loc):
    response = api.post("/mission", body)

    assert loc in schema_error_locs(response)
    assert all(error["msg"] and error["type"] for error in response.json()["detail"])
    assert not Mission.objects.exists()


def test_a_move_error_says_what_is_wrong(api):
    response = api.post("/mission", mission({"move": {"distance": 1, "rotation": 1}}))

    assert response.json()["detail"] == [
        {
            "loc": ["body", "mission_tree", 0, "move"],
            "msg": "Exactly one of distance or rotation must be set, but 2 are set.",
            "type": "move_exactly_one",
        }
    ]


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "1e999"])
def test_non_finite_waypoints_are_refused(api, literal):
    body = '{"robot": "carter01", "mission_tree": [{"route": {"waypoints": [{"x": ' + literal + "}]}}]}"

    response = api.post("/mission", body, content_type="application/json")

    assert response.status_code == 400
    assert not Mission.objects.exists()


def test_errors_in_several_nodes_are_all_reported(api):
    response = api.post("/mission", mission({"move": {"distance": "x"}}, route(extra=1), route()))

    assert schema_error_locs(response) == [
        ["body", "mission_tree", 0, "move", "distance"],
        ["body", "mission_tree", 1, "extra"],
    ]


@pytest.mark.parametrize(
    ("raw", "error"),
    [
        ("null", {"loc": ["body"], "msg": "No data provided", "type": "null"}),
        (
            "[]",
            {"loc": ["body"], "msg": "Invalid data. Expected a dictionary, but got list.", "type": "invalid"},
        ),
        (
            '"go"',
            {"loc": ["body"], "msg": "Invalid data. Expected a dictionary, but got str.", "type": "invalid"},
        ),
        (
            '{"robot": "carter01", "mission_tree": [null]}',
            {"loc": ["body", "mission_tree", 0], "msg": "This field may not be null.", "type": "null"},
        ),
    ],
)
def test_bodies_that_are_no_mission_get_drfs_exact_errors(api, raw, error):
    response = api.post("/mission", raw, content_type="application/json")

    assert response.status_code == 400
    assert response.json() == {"detail": [error]}


def test_an_invalid_body_leaves_nothing_behind_for_the_next_one(api):
    """Every request is validated by the same serializer instance (kit.api.serializers.body_validated)."""
    api.post("/mission", mission({"move": {"distance": "x"}}, route(extra=1), name="bad"))

    response = api.post("/mission", mission(route(name="go"), name="good"))

    assert response.status_code == 200, response.json()
    assert response.json()["mission_tree"][0]["route"] == {"waypoints": [waypoint(1, 2)]}


@pytest.mark.django_db(transaction=True)
def test_a_mission_posted_while_redis_is_away_is_created_and_its_robot_stepped_once_redis_is_back(
    api, tmp_path
):
    private = PrivateRedis(tmp_path)
    with live_state_in(private.url):  # nothing listens there yet
        response = api.post(
            "/mission", {"robot": "redisless01", "mission_tree": ROUTE_TREE, "name": "m-redisless"}
        )

        assert response.status_code == 200, response.content
        assert Mission.objects.filter(name="m-redisless", robot="redisless01").exists()
        private.start()
        try:
            wait_for(lambda: private.client().exists(livestate.step_marker_key("redisless01")), timeout=10)
            assert step_requests.wait_until_queued(timeout=10)  # its task is sent after its marker
        finally:
            private.kill()
