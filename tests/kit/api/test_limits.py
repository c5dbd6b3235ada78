"""The API's limits (README.md, "Limits"): each just under its bound is accepted, just over is a 400 saying
which; and input PostgreSQL or the VDA 5050 encoder cannot take (NUL, unpaired surrogates, infinities,
integers beyond 64 bits) is a 400, never a 500."""

import json

import pytest
import requests
from django.conf import settings

from kit.api.fields import MAX_SECONDS
from kit.api.names import OBJECT_NAME_MAX_LENGTH
from missions.filters import MOST_RECENT_MAX
from missions.models import Mission
from missions.tuning import MAX_NOTIFY_TIMEOUT
from robots.models import Robot
from tests.factories import MissionFactory, RobotFactory

pytestmark = pytest.mark.django_db

JSON = "application/json"
# Containers around a mission's action parameters: the body, mission_tree, the node, its action.
PARAMETERS_DEPTH = 4


def errors(response) -> list[dict]:
    assert response.status_code == 400, response.content
    return response.json()["detail"]


def error_at(response, loc: list) -> dict:
    found = {tuple(error["loc"]): error for error in errors(response)}
    assert tuple(loc) in found, found
    return found[tuple(loc)]


def action_mission(parameters: object, **action) -> dict:
    node = {"action": {"action_type": "dummy_action", "action_parameters": parameters, **action}}
    return {"robot": "carter01", "mission_tree": [node]}


def notify_mission(**notify) -> dict:
    return {
        "robot": "carter01",
        "mission_tree": [{"notify": {"url": "http://localhost:8000/done", **notify}}],
    }


def route_mission(waypoints: int) -> dict:
    route = {"waypoints": [{"x": index, "y": 0} for index in range(waypoints)]}
    return {"robot": "carter01", "mission_tree": [{"route": route}]}


def nested_lists(depth: int) -> object:
    value: object = 0
    for _ in range(depth):
        value = [value]
    return value


# --- the body -----------------------------------------------------------------------------------------------


def padded(body: dict, size: int) -> str:
    """`body` as JSON, padded with spaces to `size` bytes."""
    text = json.dumps(body)
    return text + " " * (size - len(text.encode()))


def test_a_body_of_the_maximum_size_is_accepted_and_one_byte_more_is_refused(api, woken):
    body = {"name": "carter01"}

    assert api.post("/robot", padded(body, settings.API_MAX_BODY_BYTES), content_type=JSON).status_code == 200
    response = api.post("/robot", padded(body, settings.API_MAX_BODY_BYTES + 1), content_type=JSON)

    assert errors(response) == [
        {
            "loc": ["body"],
            "msg": f"The body is larger than {settings.API_MAX_BODY_BYTES} bytes.",
            "type": "body_too_large",
        }
    ]


def test_nesting_to_the_maximum_depth_is_accepted_and_one_level_more_is_refused(api, woken):
    deepest = settings.API_MAX_JSON_DEPTH - PARAMETERS_DEPTH

    accepted = api.post("/mission", action_mission({"k": nested_lists(deepest - 1)}))
    refused = api.post("/mission", action_mission({"k": nested_lists(deepest)}))

    assert accepted.status_code == 200, accepted.json()
    [error] = errors(refused)
    assert error["type"] == "json_too_deep"
    assert error["msg"] == f"JSON nested deeper than {settings.API_MAX_JSON_DEPTH} levels."
    assert error["loc"][:6] == ["body", "mission_tree", 0, "action", "action_parameters", "k"]
    assert len(error["loc"]) == settings.API_MAX_JSON_DEPTH + 1


@pytest.mark.parametrize("raw", ["[" * 100_000, '{"a":' * 100_000, "[" * 100_000 + "]" * 100_000])
def test_a_hugely_nested_body_is_a_400_not_a_recursion_error(api, raw):
    response = api.post("/mission", raw, content_type=JSON)

    assert errors(response) == [
        {
            "loc": ["body"],
            "msg": f"JSON nested deeper than {settings.API_MAX_JSON_DEPTH} levels.",
            "type": "json_too_deep",
        }
    ]


# --- the mission tree ---------------------------------------------------------------------------------------


def test_a_tree_of_the_maximum_size_is_accepted_and_one_node_more_is_refused(api, woken):
    nodes = [{"constant": {}} for _ in range(settings.API_MAX_TREE_NODES + 1)]

    accepted = api.post("/mission", {"robot": "carter01", "mission_tree": nodes[:-1]})
    refused = api.post("/mission", {"robot": "carter01", "mission_tree": nodes})

    assert accepted.status_code == 200, accepted.json()
    assert len(accepted.json()["mission_tree"]) == settings.API_MAX_TREE_NODES
    error = error_at(refused, ["body", "mission_tree"])
    assert error["type"] == "max_length"
    assert str(settings.API_MAX_TREE_NODES) in error["msg"]


def test_a_route_of_the_maximum_length_is_accepted_and_one_waypoint_more_is_refused(api, woken):
    accepted = api.post("/mission", route_mission(settings.API_MAX_WAYPOINTS))
    refused = api.post("/mission", route_mission(settings.API_MAX_WAYPOINTS + 1))

    assert accepted.status_code == 200, accepted.json()
    error = error_at(refused, ["body", "mission_tree", 0, "route", "waypoints"])
    assert error["type"] == "max_length"


def test_route_updates_are_bounded_like_a_route_and_a_tree(api, woken):
    mission = MissionFactory(robot="carter01")
    waypoints = [{"x": 1, "y": 1}] * (settings.API_MAX_WAYPOINTS + 1)
    too_many_nodes = {
        f"n{index}": {"waypoints": [{"x": 1}]} for index in range(settings.API_MAX_TREE_NODES + 1)
    }

    long_route = api.post(f"/mission/{mission.name}/update", {"goto": {"waypoints": waypoints}})
    many_routes = api.post(f"/mission/{mission.name}/update", too_many_nodes)

    assert error_at(long_route, ["body", "goto", "waypoints"])["type"] == "max_length"
    assert error_at(many_routes, ["body"])["type"] == "max_length"


@pytest.mark.parametrize("field", ["action_parameters", "json_data"])
def test_free_json_of_the_maximum_size_is_accepted_and_one_byte_more_is_refused(api, woken, field):
    def body(size: int) -> dict:
        # {"k":"xxx"}: eight bytes around the text.
        value = {"k": "x" * (size - 8)}
        return action_mission(value) if field == "action_parameters" else notify_mission(json_data=value)

    accepted = api.post("/mission", body(settings.API_MAX_PARAMETERS_BYTES))
    refused = api.post("/mission", body(settings.API_MAX_PARAMETERS_BYTES + 1))

    assert accepted.status_code == 200, accepted.json()
    kind = "action" if field == "action_parameters" else "notify"
    error = error_at(refused, ["body", "mission_tree", 0, kind, field])
    assert error["type"] == "too_large"
    limit = settings.API_MAX_PARAMETERS_BYTES
    assert error["msg"] == f"Larger than {limit} bytes as JSON ({limit + 1})."


def test_action_parameters_hold_64_bit_integers_and_no_larger(api, woken):
    accepted = api.post("/mission", action_mission({"low": -(2**63), "high": 2**63 - 1}))
    refused = api.post("/mission", action_mission({"nested": [{"count": 2**63}]}))

    assert accepted.status_code == 200, accepted.json()
    assert error_at(refused, ["body", "mission_tree", 0, "action", "action_parameters"])["type"] == "int64"


@pytest.mark.parametrize("kind", ["action", "notify"])
def test_infinity_in_free_json_is_refused(api, kind):
    raw = json.dumps(action_mission({"k": 1}) if kind == "action" else notify_mission(json_data={"k": 1}))

    response = api.post("/mission", raw.replace('"k": 1', '"k": 1e999'), content_type=JSON)

    field = "action_parameters" if kind == "action" else "json_data"
    assert error_at(response, ["body", "mission_tree", 0, kind, field])["type"] == "finite_number"
    assert not Mission.objects.exists()


# --- strings ------------------------------------------------------------------------------------------------

TEXT_FIELDS = {
    "action_type": lambda text: action_mission({}, action_type=text),
    "url": lambda text: notify_mission(url=f"http://example.com/{text}"[: len(text)]),
    "map_id": lambda text: {
        "robot": "carter01",
        "mission_tree": [{"route": {"waypoints": [{"map_id": text}]}}],
    },
}
TEXT_LOCS = {
    "action_type": ["body", "mission_tree", 0, "action", "action_type"],
    "url": ["body", "mission_tree", 0, "notify", "url"],
    "map_id": ["body", "mission_tree", 0, "route", "waypoints", 0, "map_id"],
}


@pytest.mark.parametrize("field", sorted(TEXT_FIELDS))
def test_free_text_of_the_maximum_length_is_accepted_and_one_character_more_is_refused(api, woken, field):
    build = TEXT_FIELDS[field]

    accepted = api.post("/mission", build("a" * settings.API_MAX_TEXT_LENGTH))
    refused = api.post("/mission", build("a" * (settings.API_MAX_TEXT_LENGTH + 1)))

    assert accepted.status_code == 200, accepted.json()
    assert error_at(refused, TEXT_LOCS[field])["type"] == "max_length"


def test_labels_are_bounded_in_number_and_length(api, woken):
    longest = "l" * settings.API_MAX_TEXT_LENGTH
    accepted = api.post("/robot", {"name": "carter01", "labels": [longest] * settings.API_MAX_LABELS})
    too_many = api.post("/robot", {"name": "carter02", "labels": ["a"] * (settings.API_MAX_LABELS + 1)})
    too_long = api.post("/robot", {"name": "carter03", "labels": [longest + "l"]})

    assert accepted.status_code == 200, accepted.json()
    assert error_at(too_many, ["body", "labels"])["type"] == "max_length"
    assert error_at(too_long, ["body", "labels", 0])["type"] == "max_length"


NAME_FIELDS = {
    "robot name": ("/robot", lambda name: {"name": name}, ["body", "name"]),
    "mission name": (
        "/mission",
        lambda name: {**route_mission(1), "name": name},
        ["body", "name"],
    ),
    "mission robot": ("/mission", lambda name: {**route_mission(1), "robot": name}, ["body", "robot"]),
    "node name": (
        "/mission",
        lambda name: {"robot": "carter01", "mission_tree": [{"name": name, "constant": {}}]},
        ["body", "mission_tree", 0, "name"],
    ),
    "serial number": (
        "/robot",
        lambda name: {"vda5050": {"serial_number": name}},
        ["body", "vda5050", "serial_number"],
    ),
    "manufacturer": (
        "/robot",
        lambda name: {"vda5050": {"manufacturer": name}},
        ["body", "vda5050", "manufacturer"],
    ),
    "interface name": (
        "/robot",
        lambda name: {"vda5050": {"interface_name": name}},
        ["body", "vda5050", "interface_name"],
    ),
}


@pytest.mark.parametrize("field", sorted(NAME_FIELDS))
def test_names_fit_their_database_columns(api, woken, field):
    """Names are primary keys or VDA 5050 identity columns of 100 characters."""
    path, build, loc = NAME_FIELDS[field]
    assert Robot._meta.get_field("name").max_length == OBJECT_NAME_MAX_LENGTH
    assert Robot._meta.get_field("serial_number").max_length == OBJECT_NAME_MAX_LENGTH
    assert Mission._meta.get_field("robot").max_length == OBJECT_NAME_MAX_LENGTH

    accepted = api.post(path, build("n" * OBJECT_NAME_MAX_LENGTH))
    refused = api.post(path, build("n" * (OBJECT_NAME_MAX_LENGTH + 1)))

    assert accepted.status_code == 200, accepted.json()
    assert error_at(refused, loc)["type"] == "max_length"


def test_a_parent_is_a_name_too(api):
    response = api.post(
        "/mission", {"robot": "carter01", "mission_tree": [{"parent": "p" * 101, "constant": {}}]}
    )

    assert error_at(response, ["body", "mission_tree", 0, "parent"])["type"] == "max_length"


@pytest.mark.parametrize(
    ("text", "loc"),
    [
        ('{"k": "a\\u0000b"}', ["body", "mission_tree", 0, "action", "action_parameters", "k"]),
        ('{"a\\u0000": 1}', ["body", "mission_tree", 0, "action", "action_parameters"]),
        ('{"k": ["\\ud800"]}', ["body", "mission_tree", 0, "action", "action_parameters", "k", 0]),
    ],
)
def test_text_postgresql_cannot_store_is_refused_wherever_it_is(api, text, loc):
    raw = json.dumps(action_mission({})).replace('"action_parameters": {}', f'"action_parameters": {text}')

    response = api.post("/mission", raw, content_type=JSON)

    assert errors(response) == [
        {
            "loc": loc,
            "msg": "Text must not contain NUL characters or unpaired surrogates.",
            "type": "invalid_text",
        }
    ]
    assert not Mission.objects.exists()


def test_a_surrogate_pair_is_text_like_any_other(api, woken):
    raw = json.dumps(action_mission({"k": "\U0001f916"}))  # json.dumps writes it as a \ud83e\udd16 pair

    response = api.post("/mission", raw, content_type=JSON)

    assert response.status_code == 200, response.json()
    assert response.json()["mission_tree"][0]["action"]["action_parameters"] == {"k": "\U0001f916"}


@pytest.mark.parametrize("field", ["name", "robot"])
def test_nul_in_a_name_is_refused(api, field):
    body = {**route_mission(1), field: "car\u0000ter"}

    assert error_at(api.post("/mission", body), ["body", field])["type"] == "invalid_text"


# --- durations ----------------------------------------------------------------------------------------------


def test_durations_are_bounded(api, woken):
    assert api.post("/mission", {**route_mission(1), "timeout": MAX_SECONDS}).status_code == 200
    assert api.post("/robot", {"name": "carter01", "heartbeat_timeout": MAX_SECONDS}).status_code == 200
    assert api.post("/mission", notify_mission(timeout=MAX_NOTIFY_TIMEOUT)).status_code == 200

    mission = api.post("/mission", {**route_mission(1), "timeout": MAX_SECONDS * 1.000001})
    robot = api.post("/robot", {"name": "carter02", "heartbeat_timeout": MAX_SECONDS * 1.000001})
    notify = api.post("/mission", notify_mission(timeout=MAX_NOTIFY_TIMEOUT + 1))

    assert error_at(mission, ["body", "timeout"])["type"] == "max_value"
    assert error_at(robot, ["body", "heartbeat_timeout"])["type"] == "max_value"
    assert error_at(notify, ["body", "mission_tree", 0, "notify", "timeout"])["type"] == "max_value"


# --- JSON types: the schema's, without coercion -------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "body", "loc"),
    [
        ("/robot", {"name": 7}, ["body", "name"]),
        ("/robot", {"labels": [7]}, ["body", "labels", 0]),
        ("/robot", {"heartbeat_timeout": "30"}, ["body", "heartbeat_timeout"]),
        ("/robot", {"heartbeat_timeout": True}, ["body", "heartbeat_timeout"]),
        ("/robot", {"switch_teleop": "true"}, ["body", "switch_teleop"]),
        ("/robot", {"switch_teleop": 1}, ["body", "switch_teleop"]),
        ("/robot", {"vda5050": {"serial_number": 0}}, ["body", "vda5050", "serial_number"]),
        ("/mission", {**route_mission(1), "robot": 1}, ["body", "robot"]),
        ("/mission", {**route_mission(1), "needs_canceled": "false"}, ["body", "needs_canceled"]),
        (
            "/mission",
            {"robot": "r", "mission_tree": [{"constant": {"success": 0}}]},
            ["body", "mission_tree", 0, "constant", "success"],
        ),
        ("/mission", notify_mission(timeout="5"), ["body", "mission_tree", 0, "notify", "timeout"]),
        ("/mission", action_mission({}, action_type=5), ["body", "mission_tree", 0, "action", "action_type"]),
    ],
)
def test_values_of_another_json_type_are_refused(api, path, body, loc):
    assert error_at(api.post(path, body), loc)["type"] == "invalid"


def test_spaces_around_names_are_kept_so_the_name_is_refused(api):
    """The reference (pydantic) does not trim either; a name with spaces is no valid name."""
    assert error_at(api.post("/robot", {"name": " carter01 "}), ["body", "name"])["type"] == "invalid_name"


# --- query filters ------------------------------------------------------------------------------------------


def test_the_names_filter_takes_the_maximum_number_of_values_and_no_more(api):
    RobotFactory(name="carter01")
    names = [f"robot{index}" for index in range(settings.API_MAX_FILTER_VALUES - 1)]

    accepted = api.get("/robot", {"names": ["carter01", *names]})
    refused = api.get("/robot", {"names": ["carter01", *names, "one_more"]})

    assert accepted.status_code == 200
    assert [robot["name"] for robot in accepted.json()] == ["carter01"]
    error = error_at(refused, ["query", "names"])
    assert error["type"] == "max_length"
    assert error["msg"] == (
        f"At most {settings.API_MAX_FILTER_VALUES} values, not {settings.API_MAX_FILTER_VALUES + 1}."
    )


def test_more_query_parameters_than_django_parses_are_a_json_400(api):
    response = api.get("/robot", {"names": ["a"] * (settings.DATA_UPLOAD_MAX_NUMBER_FIELDS + 1)})

    assert errors(response) == [
        {
            "loc": ["query"],
            "msg": f"More than {settings.DATA_UPLOAD_MAX_NUMBER_FIELDS} query parameters.",
            "type": "too_many_parameters",
        }
    ]


def test_nul_among_names_is_a_400(api):
    response = api.get("/robot?names=carter01&names=car%00ter")

    assert errors(response) == [
        {"loc": ["query", "names"], "msg": "Must not contain NUL characters.", "type": "null_characters"}
    ]


@pytest.mark.parametrize(
    ("path", "parameter", "value"),
    [
        ("/mission", "robot", "car%00ter"),
        ("/mission", "started_after", "2024-01-01T00:00:00%00"),
        ("/mission", "state", "RUNNING%00"),
        ("/robot", "online", "true%00"),
    ],
)
def test_nul_in_any_filter_is_a_400(api, path, parameter, value):
    error = error_at(api.get(f"{path}?{parameter}={value}"), ["query", parameter])

    assert error in [
        {"loc": ["query", parameter], "msg": "Must not contain NUL characters.", "type": "null_characters"},
        {
            "loc": ["query", parameter],
            "msg": "Null characters are not allowed.",
            "type": "null_characters_not_allowed",
        },
    ]


def test_most_recent_takes_any_64_bit_limit(api):
    MissionFactory(robot="carter01")

    accepted = api.get("/mission", {"most_recent": MOST_RECENT_MAX})
    refused = api.get("/mission", {"most_recent": MOST_RECENT_MAX + 1})
    huge = api.get("/mission", {"most_recent": "9" * 40})

    assert accepted.status_code == 200
    assert len(accepted.json()) == 1
    assert error_at(refused, ["query", "most_recent"])["type"] == "max_value"
    assert error_at(huge, ["query", "most_recent"])["type"] == "max_value"


@pytest.mark.parametrize(
    ("path", "parameter"),
    [
        ("/robot", "state"),
        ("/robot", "online"),
        ("/robot", "min_battery"),
        ("/robot", "names"),
        ("/robot", "robot_type"),
        ("/mission", "state"),
        ("/mission", "robot"),
        ("/mission", "started_after"),
        ("/mission", "most_recent"),
    ],
)
def test_an_empty_filter_value_is_refused_not_ignored(api, path, parameter):
    assert error_at(api.get(f"{path}?{parameter}="), ["query", parameter]) == {
        "loc": ["query", parameter],
        "msg": "Must not be empty.",
        "type": "blank",
    }


# --- names in the path --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "path", "detail"),
    [
        ("get", "/robot/car%00ter", 'Did not find "robot" with name "car\u0000ter"'),
        ("put", "/robot/car%00ter", "Could not find object car\u0000ter"),
        ("delete", "/robot/car%00ter", "Could not find object car\u0000ter"),
        ("post", "/robot/car%00ter/teleop?params=START", 'Did not find "robot" with name "car\u0000ter"'),
        ("get", "/mission/m%00", 'Did not find "mission" with name "m\u0000"'),
        ("delete", "/mission/m%00", "Could not find object m\u0000"),
        ("post", "/mission/m%00/cancel", 'Did not find "mission" with name "m\u0000"'),
        ("post", "/mission/m%00/update", 'Did not find "mission" with name "m\u0000"'),
    ],
)
def test_a_name_no_object_can_have_is_not_found(api, woken, method, path, detail):
    RobotFactory(name="carter01")

    response = getattr(api, method)(path, {}, format="json")

    assert response.status_code == 400
    assert response.json() == {"detail": detail}


# --- through the real server --------------------------------------------------------------------------------


def test_the_server_answers_limits_with_json_400s_and_keeps_its_worker(api_server):
    post = lambda data, **headers: requests.post(  # noqa: E731
        f"{api_server.url}/robot",
        data=data,
        headers={"Content-Type": JSON, **api_server.auth, **headers},
        timeout=30,
    )

    too_large = post(padded({"name": "carter01"}, settings.API_MAX_BODY_BYTES + 1))
    too_deep = post("[" * 100_000)
    chunked = post(iter([b'{"name": "carter01"}']))
    too_many = requests.get(
        f"{api_server.url}/robot",
        params={"names": ["a"] * (settings.DATA_UPLOAD_MAX_NUMBER_FIELDS + 1)},
        headers=api_server.auth,
        timeout=30,
    )
    accepted = post(padded({"name": "carter01"}, settings.API_MAX_BODY_BYTES))

    assert [error_at(too_large, ["body"])["type"], error_at(too_deep, ["body"])["type"]] == [
        "body_too_large",
        "json_too_deep",
    ]
    assert error_at(chunked, ["body"]) == {
        "loc": ["body"],
        "msg": "A body needs a Content-Length header.",
        "type": "length_required",
    }
    assert error_at(too_many, ["query"])["type"] == "too_many_parameters"
    assert accepted.status_code == 200, accepted.text
    assert api_server.process.poll() is None
    assert "Traceback" not in api_server.output()
    assert api_server.output().count("Spawning worker") == 1  # never respawned
