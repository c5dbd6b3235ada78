"""The OpenAPI schema (/openapi.json) and the Swagger UI (/docs): valid, complete, and served offline."""

import json
import re

import jsonschema
import pytest
from django.conf import settings
from drf_spectacular.drainage import GENERATOR_STATS
from drf_spectacular.generators import SchemaGenerator
from drf_spectacular.validation import validate_schema

from kit.api.fields import MAX_SECONDS
from kit.api.names import OBJECT_NAME_MAX_LENGTH
from missions.tuning import MAX_NOTIFY_TIMEOUT
from stations.models import MAX_CAPACITY
from tests.readme import README_MISSIONS, README_ROBOT, UNBOUND_MISSION_EXAMPLE
from zones.models import MAX_CAPACITY as MAX_ZONE_CAPACITY
from zones.models import MAX_VERTICES, MAX_ZONES

ENDPOINTS = {
    "/robot": {"get", "post"},
    "/robot/{name}": {"get", "put", "delete"},
    "/robot/{name}/teleop": {"post"},
    "/robot/{name}/charge": {"post"},
    "/robot/{name}/map": {"get", "post"},
    "/mission": {"get", "post"},
    "/mission/{name}": {"get", "delete"},
    "/mission/{name}/cancel": {"post"},
    "/mission/{name}/update": {"post"},
    "/station": {"get", "post"},
    "/station/{name}": {"get", "put", "delete"},
    "/zone_set": {"get", "post"},
    "/zone_set/{name}": {"get", "delete"},
    "/zone_set/{name}/enable": {"post"},
    "/zone_set/{name}/disable": {"post"},
    "/zone_set/{name}/revoke": {"post"},
    "/health": {"get"},
    "/behaviors": {"get"},
}
ROBOT_FILTERS = {
    "min_battery",
    "max_battery",
    "state",
    "online",
    "position_initialized",
    "names",
    "robot_type",
}
MISSION_FILTERS = {"state", "started_after", "started_before", "robot", "unbound", "most_recent"}
STATION_FILTERS = {"kind", "map_id", "robot_type", "names"}
ZONE_SET_FILTERS = {"map_id", "enabled", "names"}


@pytest.fixture(scope="module")
def schema() -> dict:
    return SchemaGenerator().get_schema(request=None, public=True)


def query_parameters(operation: dict) -> dict[str, dict]:
    return {
        parameter["name"]: parameter for parameter in operation["parameters"] if parameter["in"] == "query"
    }


def request_examples(operation: dict) -> dict[str, object]:
    examples = operation["requestBody"]["content"]["application/json"]["examples"]
    return {example["summary"]: example["value"] for example in examples.values()}


def test_schema_is_valid_openapi(schema):
    validate_schema(schema)


def test_schema_generation_has_no_warnings():
    GENERATOR_STATS.reset()

    SchemaGenerator().get_schema(request=None, public=True)

    assert not GENERATOR_STATS, "drf-spectacular warned while generating the schema (see stderr)"


def test_every_endpoint_is_documented_with_a_summary_and_a_400(schema):
    assert {path: set(operations) for path, operations in schema["paths"].items()} == ENDPOINTS
    for operations in schema["paths"].values():
        for operation in operations.values():
            assert operation["summary"]
            assert "200" in operation["responses"]
    for path, operations in schema["paths"].items():
        if path not in {"/health", "/behaviors"}:
            assert all("400" in operation["responses"] for operation in operations.values()), path


def test_every_operation_has_a_success_example(schema):
    for path, operations in schema["paths"].items():
        for method, operation in operations.items():
            success = operation["responses"]["200"]["content"]["application/json"]
            request = operation.get("requestBody", {}).get("content", {}).get("application/json", {})
            assert success.get("examples") or request.get("examples"), f"{method.upper()} {path}"


def test_every_reference_resolves(schema):
    text = repr(schema)
    for reference in set(re.findall(r"#/components/schemas/(\w+)", text)):
        assert reference in schema["components"]["schemas"], reference


def test_filters_are_documented(schema):
    robot_filters = query_parameters(schema["paths"]["/robot"]["get"])
    mission_filters = query_parameters(schema["paths"]["/mission"]["get"])

    assert set(robot_filters) == ROBOT_FILTERS
    assert set(mission_filters) == MISSION_FILTERS
    assert all(
        parameter.get("description") for parameter in [*robot_filters.values(), *mission_filters.values()]
    )
    assert robot_filters["names"]["schema"]["type"] == "array"
    assert robot_filters["names"]["explode"] is True
    assert {"ARM", "AMR", "FORKLIFT", "HUMANOID"} <= set(robot_filters["robot_type"]["schema"]["enum"])
    assert robot_filters["online"]["schema"]["type"] == "boolean"
    assert mission_filters["started_after"]["schema"]["format"] == "date-time"
    assert mission_filters["most_recent"]["schema"]["type"] == "integer"
    assert mission_filters["unbound"]["schema"]["type"] == "boolean"


def test_teleop_takes_its_action_in_the_params_query_parameter(schema):
    parameters = query_parameters(schema["paths"]["/robot/{name}/teleop"]["post"])

    assert set(parameters) == {"params"}
    assert parameters["params"]["required"] is True
    assert parameters["params"]["schema"]["enum"] == ["START", "STOP"]


def test_the_readme_examples_are_the_documented_request_examples(schema):
    assert request_examples(schema["paths"]["/mission"]["post"]) == {
        **README_MISSIONS,
        UNBOUND_MISSION_EXAMPLE["name"]: UNBOUND_MISSION_EXAMPLE,
    }
    assert list(request_examples(schema["paths"]["/robot"]["post"]).values()) == [README_ROBOT]


def test_mission_nodes_document_every_kind(schema):
    properties = schema["components"]["schemas"]["MissionNodeRequest"]["properties"]

    assert set(properties) == {
        "name",
        "parent",
        "selector",
        "sequence",
        "route",
        "move",
        "action",
        "notify",
        "constant",
    }


@pytest.mark.django_db
def test_openapi_json_is_served(api):
    response = api.get("/openapi.json")

    assert response.status_code == 200
    assert response["Content-Type"].startswith("application/vnd.oai.openapi+json")
    assert set(json.loads(response.content)["paths"]) == set(ENDPOINTS)


@pytest.mark.django_db
def test_docs_render_swagger_ui_from_local_static_files(api):
    response = api.get("/docs")

    assert response.status_code == 200
    html = response.content.decode()
    assert "swagger-ui" in html
    assert not re.search(r"(src|href)=\"https?://", html)
    assert "cdn" not in html.lower()
    scripts = re.findall(r'src="([^"]+\.js)"', html)
    assert scripts
    for script in scripts:
        assert script.startswith("/static/")
        assert api.get(script).status_code == 200


def test_a_mission_node_has_exactly_one_kind_in_the_schema_too(schema):
    """The server refuses a node with two kinds or none; the request schema says so with oneOf."""
    node = schema["components"]["schemas"]["MissionNodeRequest"]
    one_kind = {"oneOf": node["oneOf"]}
    route = {"waypoints": [{"x": 1}]}

    jsonschema.validate({"name": "a", "route": route}, one_kind)
    jsonschema.validate({"route": route, "action": None, "selector": None}, one_kind)
    for invalid in ({"route": route, "constant": {}}, {"name": "a"}, {"route": None, "move": None}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(invalid, one_kind)


def test_the_schema_states_the_limits(schema):
    schemas = schema["components"]["schemas"]
    mission = schemas["MissionCreateRequest"]["properties"]
    robot = schemas["RobotCreateRequest"]["properties"]
    most_recent = query_parameters(schema["paths"]["/mission"]["get"])["most_recent"]["schema"]
    names = query_parameters(schema["paths"]["/robot"]["get"])["names"]["schema"]

    assert (mission["mission_tree"]["minItems"], mission["mission_tree"]["maxItems"]) == (
        1,
        settings.API_MAX_TREE_NODES,
    )
    assert schemas["RouteNodeRequest"]["properties"]["waypoints"]["maxItems"] == settings.API_MAX_WAYPOINTS
    update = schema["paths"]["/mission/{name}/update"]["post"]["requestBody"]["content"]["application/json"]
    assert update["schema"]["maxProperties"] == settings.API_MAX_TREE_NODES
    assert mission["update_nodes"]["maxProperties"] == settings.API_MAX_TREE_NODES
    assert (
        schemas["ActionNodeRequest"]["properties"]["action_type"]["maxLength"] == settings.API_MAX_TEXT_LENGTH
    )
    assert schemas["NotifyNodeRequest"]["properties"]["url"]["maxLength"] == settings.API_MAX_TEXT_LENGTH
    assert schemas["NotifyNodeRequest"]["properties"]["timeout"]["maximum"] == MAX_NOTIFY_TIMEOUT
    assert schemas["Pose2DRequest"]["properties"]["map_id"]["maxLength"] == settings.API_MAX_TEXT_LENGTH
    assert mission["timeout"]["maximum"] == MAX_SECONDS
    assert mission["robot"]["maxLength"] == OBJECT_NAME_MAX_LENGTH
    assert robot["heartbeat_timeout"]["maximum"] == MAX_SECONDS
    assert robot["labels"]["maxItems"] == settings.API_MAX_LABELS
    assert robot["labels"]["items"]["maxLength"] == settings.API_MAX_TEXT_LENGTH
    assert (most_recent["minimum"], most_recent["maximum"]) == (0, 2**63 - 1)
    assert names["maxItems"] == settings.API_MAX_FILTER_VALUES
    assert (names["items"]["minLength"], names["items"]["pattern"]) == (1, "^[^\\u0000]*$")


def test_the_station_filters_and_limits_are_documented(schema):
    filters = query_parameters(schema["paths"]["/station"]["get"])
    station = schema["components"]["schemas"]["StationCreateRequest"]["properties"]

    assert set(filters) == STATION_FILTERS
    assert all(parameter.get("description") for parameter in filters.values())
    assert filters["names"]["schema"]["maxItems"] == settings.API_MAX_FILTER_VALUES
    assert set(filters["kind"]["schema"]["enum"]) == {"CHARGER", "PARKING"}
    assert (station["capacity"]["minimum"], station["capacity"]["maximum"]) == (1, MAX_CAPACITY)
    assert "#/components/schemas/PoseRequest" in json.dumps(station["pose"])


def test_the_zone_set_filters_zone_types_and_limits_are_documented(schema):
    filters = query_parameters(schema["paths"]["/zone_set"]["get"])
    components = schema["components"]["schemas"]
    zone_set = components["ZoneSetCreateRequest"]["properties"]
    zone = components["ZoneRequest"]["properties"]

    assert set(filters) == ZONE_SET_FILTERS
    assert all(parameter.get("description") for parameter in filters.values())
    assert zone_set["zones"]["maxItems"] == MAX_ZONES
    assert (zone["vertices"]["minItems"], zone["vertices"]["maxItems"]) == (3, MAX_VERTICES)
    assert (zone["capacity"]["minimum"], zone["capacity"]["maximum"]) == (1, MAX_ZONE_CAPACITY)
    assert set(components["ZoneTypeEnum"]["enum"]) == {
        "BLOCKED",
        "LINE_GUIDED",
        "RELEASE",
        "COORDINATED_REPLANNING",
        "SPEED_LIMIT",
        "ACTION",
        "PRIORITY",
        "PENALTY",
        "DIRECTED",
        "BIDIRECTED",
    }
    assert "put" not in schema["paths"]["/zone_set/{name}"]


def test_a_robots_zone_access_is_documented(schema):
    components = schema["components"]["schemas"]
    access = components["RobotZoneAccess"]

    assert components["RobotStatus"]["properties"]["zone_access"] == {
        "$ref": "#/components/schemas/RobotZoneAccess"
    }
    assert set(access["required"]) == {"held", "waiting"}
    assert all(access["properties"][field]["description"] for field in ("held", "waiting"))
    assert set(components["ZoneRef"]["required"]) == {"map_id", "zone_id"}


PUBLIC_OPERATIONS = {("/health", "get")}


def test_the_bearer_scheme_is_declared_for_swagger_uis_authorize(schema):
    assert schema["components"]["securitySchemes"]["bearerAuth"] == {
        "type": "http",
        "scheme": "bearer",
        "description": "An API token (`python manage.py api_token create NAME`).",
    }


def test_every_protected_operation_needs_credentials_and_declares_401_and_403(schema):
    for path, operations in schema["paths"].items():
        for method, operation in operations.items():
            if (path, method) in PUBLIC_OPERATIONS:
                assert "security" not in operation, path
                assert not {"401", "403"} & set(operation["responses"]), path
                continue
            assert operation["security"] == [{"bearerAuth": []}, {"cookieAuth": []}], f"{method} {path}"
            for status in ("401", "403"):
                body = operation["responses"][status]["content"]["application/json"]
                assert body["schema"] == {"$ref": "#/components/schemas/AuthError"}, f"{method} {path}"


def test_in_open_mode_the_schema_asks_for_no_credentials(settings):
    settings.API_AUTH = False

    schema = SchemaGenerator().get_schema(request=None, public=True)

    for operations in schema["paths"].values():
        for operation in operations.values():
            assert "security" not in operation
            assert not {"401", "403"} & set(operation["responses"])
