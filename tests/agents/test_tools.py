"""The tools through the SDK's client against a real server: their schemas, the reference's tools answering
what REST answers on the same data, the tools beyond the reference, and bad arguments as tool errors."""

from datetime import UTC, datetime, timedelta

import pytest

from tests.agents.conftest import text
from tests.e2e.helpers import route, wait_mission, wait_mission_where

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

REFERENCE_TOOLS = {
    "test_mission_dispatch_connection": set(),
    "get_robot_status": {"state", "robot_name"},
    "get_mission_status": {"state", "robot"},
    "get_robots_on_missions": set(),
    "get_idle_robots": set(),
    "get_fleet_summary": set(),
    "check_robot_health": {"min_battery"},
    "get_mission_queue": set(),
    "get_recent_failures": set(),
    "create_robot": {"name", "labels"},
    "dispatch_mission": {"robot", "x", "y", "theta", "mission_name"},
}
MORE_TOOLS = {
    "cancel_mission",
    "start_teleop",
    "stop_teleop",
    "update_route",
    "create_mission",
    "get_mission",
    "list_stations",
}


def test_tools_are_listed_with_their_schemas(mcp):
    tools = mcp.tools()
    assert set(tools) == set(REFERENCE_TOOLS) | MORE_TOOLS
    for name, arguments in REFERENCE_TOOLS.items():
        assert arguments <= set(tools[name].inputSchema["properties"]), name
    for tool in tools.values():
        assert len(tool.description) > 40, tool.name
    dispatch = tools["dispatch_mission"].inputSchema
    assert set(dispatch["required"]) == {"robot", "x", "y"}
    assert dispatch["properties"]["x"]["type"] == "number"
    states = tools["get_robot_status"].inputSchema["properties"]["state"]["anyOf"][0]["enum"]
    assert states == ["IDLE", "ON_TASK", "CHARGING", "MAP_DEPLOYMENT", "TELEOP"]
    assert tools["check_robot_health"].inputSchema["properties"]["min_battery"]["type"] == "number"
    assert tools["get_fleet_summary"].annotations.readOnlyHint is True
    assert tools["dispatch_mission"].annotations.readOnlyHint is False
    # Any mission tree: POST /mission's body as the API's OpenAPI schema states it.
    tree = tools["create_mission"].inputSchema
    assert set(tree["required"]) == {"mission_tree"}  # without a robot: assignment picks one
    assert {"robot", "priority", "robot_selector"} <= set(tree["properties"])
    assert tree["properties"]["mission_tree"]["items"] == {"$ref": "#/$defs/MissionNodeRequest"}
    assert {"route", "action", "selector"} <= set(tree["$defs"]["MissionNodeRequest"]["properties"])


def _post(api, path, body):
    response = api.post(path, body)
    assert response.status_code == 200, response.content
    return response.json()


def test_reference_tools_answer_what_rest_answers(mcp, api, unique):
    idle, other = unique("idle"), unique("other")
    for name in (idle, other):
        _post(api, "/robot", {"name": name, "labels": ["mcp"]})
    queued = unique("queued")
    _post(api, "/mission", {"name": queued, "robot": idle, "mission_tree": [route("r", (1, 1))]})
    past = (datetime.now(UTC) - timedelta(minutes=1)).isoformat()
    late = unique("late")
    body = {"name": late, "robot": other, "mission_tree": [route("r", (1, 1))], "deadline": past}
    _post(api, "/mission", body)
    wait_mission(api, late, {"FAILED"})  # a mission past its deadline never starts
    # The fleet at rest, so both answers see the same data: the queued mission waits for its robot.
    wait_mission_where(api, queued, lambda status: status["waiting_reason"], message="a waiting reason")

    robots, missions = api.get("/robot").json(), api.get("/mission").json()
    assert mcp.ok("get_robot_status").structuredContent == {"robots": robots}
    assert mcp.ok("get_robot_status", state="IDLE").structuredContent == {
        "robots": api.get("/robot?state=IDLE").json()
    }
    one = mcp.ok("get_robot_status", robot_name=idle)
    assert one.structuredContent == {"robots": [api.get(f"/robot/{idle}").json()]}
    assert f"**{idle}**" in text(one) and "Online: False" in text(one)
    assert mcp.ok("get_mission_status").structuredContent == {"missions": missions}
    by_robot = mcp.ok("get_mission_status", robot=idle).structuredContent
    assert by_robot == {"missions": api.get(f"/mission?robot={idle}").json()}
    assert mcp.ok("get_mission_status", state="FAILED").structuredContent == {
        "missions": api.get("/mission?state=FAILED").json()
    }
    assert mcp.ok("get_mission_queue").structuredContent == {
        "missions": api.get("/mission?state=PENDING").json()
    }
    failures = mcp.ok("get_recent_failures")
    assert failures.structuredContent == {"missions": api.get("/mission?state=FAILED").json()[::-1]}
    assert late in text(failures)
    assert mcp.ok("get_idle_robots").structuredContent == {"robots": api.get("/robot?state=IDLE").json()}
    charger = unique("charger")
    api.post("/station", {"name": charger, "kind": "CHARGER", "pose": {"x": 1.5}}, format="json")
    chargers = mcp.ok("list_stations", kind="CHARGER")
    assert chargers.structuredContent == {"stations": api.get("/station?kind=CHARGER").json()}
    assert charger in text(chargers)
    assert mcp.ok("get_robots_on_missions").structuredContent == {
        "robots": api.get("/robot?state=ON_TASK").json(),
        "missions": [],
    }
    summary = mcp.ok("get_fleet_summary").structuredContent
    assert summary["robots"]["total"] == len(robots) == 2
    assert summary["robots"]["online"] == 0
    assert summary["missions"] == {"total": 2, "by_state": {"FAILED": 1, "PENDING": 1}, "active": 1}
    health = mcp.ok("check_robot_health", min_battery=50).structuredContent
    assert sorted(health["offline"]) == sorted([idle, other]) and health["healthy"] == []
    connection = mcp.ok("test_mission_dispatch_connection")
    assert connection.structuredContent["robots"] == 2 and connection.structuredContent["missions"] == 2
    assert connection.structuredContent["read_only"] is False


def test_tools_beyond_the_reference(mcp, api, unique):
    robot, name = unique("r"), unique("m")
    assert api.post("/robot", {"name": robot}).status_code == 200
    tree = [
        {"name": "fallback", "selector": {}},
        route("there", (3, 4), parent="fallback"),
        {"name": "pause", "action": {"action_type": "dummy_action", "action_parameters": {"time": 1}}},
    ]
    created = mcp.ok("create_mission", robot=robot, mission_tree=tree, name=name, timeout=60)
    stored = api.get(f"/mission/{name}").json()
    assert created.structuredContent.pop("status")["state"] == "PENDING"
    assert created.structuredContent == {key: value for key, value in stored.items() if key != "status"}
    shown = mcp.ok("get_mission", name=name)
    assert shown.structuredContent == api.get(f"/mission/{name}").json()
    assert "  - fallback [selector]: PENDING" in text(shown)
    assert "    - there [route]: PENDING" in text(shown)

    waypoints = [{"x": 5, "y": 6, "theta": 0, "map_id": "map"}]
    mcp.ok("update_route", mission=name, node="there", waypoints=waypoints)
    assert api.get(f"/mission/{name}").json()["update_nodes"]["there"]["waypoints"][0]["x"] == 5

    mcp.ok("start_teleop", robot=robot)
    assert api.get(f"/robot/{robot}").json()["switch_teleop"] is True
    mcp.ok("stop_teleop", robot=robot)
    assert api.get(f"/robot/{robot}").json()["switch_teleop"] is False

    canceled = mcp.ok("cancel_mission", name=name)
    assert canceled.structuredContent["status"]["state"] == "CANCELED"
    again = mcp.call("cancel_mission", name=name)
    refused = api.post(f"/mission/{name}/cancel").json()["message"]
    assert again.isError and refused in text(again)  # the API's refusal, word for word
    assert "Traceback" not in text(again)


def test_bad_arguments_are_tool_errors_naming_the_argument(mcp, api, unique):
    not_a_number = mcp.call("dispatch_mission", robot="r1", x="north", y=1)
    assert not_a_number.isError and "x: Input should be a valid number" in text(not_a_number)
    assert "Traceback" not in text(not_a_number)
    missing = mcp.call("dispatch_mission", robot="r1", x=1)
    assert missing.isError and "y: Field required" in text(missing)
    bad_state = mcp.call("get_robot_status", state="SLEEPING")
    assert bad_state.isError and "state: Input should be 'IDLE'" in text(bad_state), text(bad_state)

    # What the API refuses, the tool refuses in the API's words, located at the argument.
    empty_route = mcp.call(
        "create_mission", robot="r1", mission_tree=[{"name": "a", "route": {"waypoints": []}}]
    )
    assert empty_route.isError
    assert "mission_tree.0.route.waypoints: " in text(empty_route), text(empty_route)
    response = api.post(
        "/mission", {"robot": "r1", "mission_tree": [{"name": "a", "route": {"waypoints": []}}]}
    )
    assert response.json()["detail"][0]["msg"] in text(empty_route)
    string_timeout = mcp.call("create_mission", robot="r1", mission_tree=[route("a", (1, 1))], timeout="30")
    assert string_timeout.isError and "timeout: " in text(string_timeout)
    bad_label = mcp.call("create_robot", name=unique("r"), labels=["x" * 3000])
    assert bad_label.isError and "labels.0: " in text(bad_label)

    robot = unique("r")
    created = mcp.ok("create_robot", name=robot, labels=["forklift", "zone:a"])
    assert created.structuredContent == api.get(f"/robot/{robot}").json()
    assert created.structuredContent["labels"] == ["forklift", "zone:a"]
    duplicate = mcp.call("create_robot", name=robot)
    assert duplicate.isError and f"Object robot with name {robot} already exists" in text(duplicate)
    missing_mission = mcp.call("get_mission", name="nowhere")
    assert missing_mission.isError and 'Did not find "mission" with name "nowhere"' in text(missing_mission)
    assert api.get("/mission").json() == []  # nothing refused was written
