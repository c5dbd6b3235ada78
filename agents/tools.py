"""The MCP server's tools: the reference's eleven (same names and arguments), then cancel, teleop, route
updates, any mission tree and one mission with its tree's node states.

Every tool reads through the selectors and the API's serializers and writes through the services, after
the API's own validation (the serializers of the REST views), so a tool answers what the REST API answers:
the same objects (structured content: the API's JSON), the same refusals (a tool error with the API's
message) and, for writes, the same write records (actor `token:<name>`, `via` mcp). A tool's Django work
runs on one of the API's request threads (`agents.http`), never in the event loop.
"""

import inspect
import json
import logging
import re
from collections import Counter
from collections.abc import Callable, Iterable
from functools import cache
from typing import Annotated, Any, Literal

from django.http import QueryDict
from mcp.server.fastmcp import Context, FastMCP
from mcp.server.fastmcp.exceptions import ToolError
from mcp.server.transport_security import TransportSecuritySettings
from mcp.types import CallToolResult, TextContent, ToolAnnotations
from mcp.types import Tool as McpTool
from pydantic import Field, ValidationError
from rest_framework.renderers import JSONRenderer

from access.choices import VIA_MCP
from access.services import writes_via
from dispatch.vocabulary import MissionState, RobotState, StationKind
from kit.api.errors import exception_handler
from kit.api.health import HEALTH_STATUS
from kit.api.serializers import body_validated
from missions.api.serializers import NODE_KINDS, MissionCreateSerializer, MissionSerializer, RouteUpdatesField
from missions.selectors import mission_get, mission_list
from missions.services import mission_cancel, mission_create, mission_update_routes
from robots.api.serializers import RobotCreateSerializer, RobotSerializer
from robots.choices import TeleopAction
from robots.selectors import robot_get, robot_list
from robots.services import robot_create, robot_teleop
from stations.api.serializers import StationSerializer
from stations.selectors import station_list

logger = logging.getLogger(__name__)

SERVER_NAME = "mission-dispatch"
# The key of a request's scope under which `agents.http` hands the tools their call (`http.Call`).
CALL = "fleet.mcp.call"
INSTRUCTIONS = (
    "Mission Dispatch runs missions on a fleet of mobile robots (VDA 5050). Read the fleet with the get_* "
    "and check_* tools; send a robot somewhere with dispatch_mission, or run any behaviour tree with "
    "create_mission; follow a mission with get_mission; stop it with cancel_mission. Names of robots, "
    "missions and nodes use only A-Z a-z 0-9 _ - . : (at most 100 characters)."
)
# The reference's default for check_robot_health: robots below this battery percentage are low.
DEFAULT_MIN_BATTERY = 20.0
# Robots listed by name in the healthy section of check_robot_health's text, as the reference shows.
HEALTHY_SHOWN = 5
ACTIVE_STATES = (MissionState.RUNNING, MissionState.PENDING)

RobotStateName = Literal[tuple(state.value for state in RobotState)]
MissionStateName = Literal[tuple(state.value for state in MissionState)]
StationKindName = Literal[tuple(kind.value for kind in StationKind)]
Name = Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9_.:-]+$")]

READS = ToolAnnotations(readOnlyHint=True, openWorldHint=False)
WRITES = ToolAnnotations(readOnlyHint=False, destructiveHint=False, openWorldHint=True)
STOPS = ToolAnnotations(readOnlyHint=False, destructiveHint=True, openWorldHint=True)


class FleetMCP(FastMCP):
    """FastMCP whose callers see and may call only the tools their token allows: a read-only token gets
    the reading tools (readOnlyHint) alone."""

    async def list_tools(self) -> list[McpTool]:
        call = self._call()
        tools = [tool for tool in await super().list_tools() if call.may_call(tool.annotations)]
        schema = await call.run(create_mission_schema)
        return [
            tool.model_copy(update={"inputSchema": schema}) if tool.name == "create_mission" else tool
            for tool in tools
        ]

    async def call_tool(self, name: str, arguments: dict[str, Any]) -> Any:
        tool = self._tool_manager.get_tool(name)
        call = self._call()
        if tool is not None and not call.may_call(tool.annotations):
            raise ToolError(f'The token "{call.caller.name}" is read-only: it may not call {name}.')
        try:
            return await super().call_tool(name, arguments)
        except ToolError as error:
            if not isinstance(error.__cause__, ValidationError):
                raise
            # Arguments of the wrong type or missing: one `argument: message` each, as the API's errors.
            wrong = "; ".join(
                f"{'.'.join(map(str, each['loc']))}: {each['msg']}" for each in error.__cause__.errors()
            )
            raise ToolError(f"Invalid arguments for {name}: {wrong}") from None

    def _call(self) -> Any:
        request = self.get_context().request_context.request
        return request.scope[CALL]


SERVER = FleetMCP(
    SERVER_NAME,
    instructions=INSTRUCTIONS,
    stateless_http=True,  # any worker process answers any request; every request is authenticated
    json_response=True,
    # Requests carry a bearer token, not cookies: no DNS rebinding to guard against, and the API's port
    # answers whatever host name it is reached by.
    transport_security=TransportSecuritySettings(enable_dns_rebinding_protection=False),
)


# --- helpers ------------------------------------------------------------------------------------------


Answer = tuple[str, dict[str, Any]]  # a tool's text, and the API's JSON as its structured content


def tool(name: str, description: str, annotations: ToolAnnotations) -> Callable[[Callable], Callable]:
    """Register `work(caller, **arguments) -> (text, data)` as the tool `name`: its arguments (and their
    schema) are `work`'s after `caller`; it runs on a request thread, its refusals become tool errors."""

    def register(work: Callable[..., Answer]) -> Callable[..., Answer]:
        async def run(ctx: Context, **arguments: Any) -> CallToolResult:
            call = ctx.request_context.request.scope[CALL]
            text, data = await call.run(
                lambda: _answer(lambda caller: work(caller, **arguments), call.caller)
            )
            return CallToolResult(content=[TextContent(type="text", text=text)], structuredContent=data)

        parameters = list(inspect.signature(work).parameters.values())[1:]
        context = inspect.Parameter("ctx", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=Context)
        run.__signature__ = inspect.Signature([context, *parameters], return_annotation=CallToolResult)
        run.__annotations__ = {"ctx": Context, **{p.name: p.annotation for p in parameters}}
        run.__name__ = work.__name__  # the name argument errors give (`dispatch_missionArguments`)
        SERVER.add_tool(run, name=name, description=description, annotations=annotations)
        return work

    return register


def _answer(work: Callable[[Any], Answer], caller: Any) -> Answer:
    try:
        with writes_via(VIA_MCP):
            return work(caller)
    except ToolError:
        raise
    except Exception as error:
        response = exception_handler(error, {})
        if response is None:
            logger.exception("MCP tool failed")
            raise ToolError("The server failed to answer; its log says why.") from None
        raise ToolError(refusal_text(response.data)) from None


def refusal_text(body: dict[str, Any]) -> str:
    """The API's error body as one line: its message, or each schema error as `argument.path: message`
    (the location without its leading "body" or "query": the tool's arguments)."""
    if "message" in body:
        return str(body["message"])
    detail = body.get("detail")
    if isinstance(detail, list):
        return "; ".join(
            f"{'.'.join(str(part) for part in error['loc'][1:]) or 'arguments'}: {error['msg']}"
            for error in detail
        )
    return str(detail)


def api_json(data: Any) -> Any:
    """`data` as the API renders it (its JSON, parsed)."""
    return json.loads(JSONRenderer().render(data))


def _query(**filters: Any) -> QueryDict:
    """GET query filters as the list selectors take them from a request; None values are left out."""
    query = QueryDict(mutable=True)
    for key, value in filters.items():
        if value is not None:
            query[key] = str(value)
    return query


def _robots(**filters: Any) -> list[dict[str, Any]]:
    return api_json(RobotSerializer(robot_list(filters=_query(**filters)), many=True).data)


def _missions(**filters: Any) -> list[dict[str, Any]]:
    return api_json(MissionSerializer(mission_list(filters=_query(**filters)), many=True).data)


def station_text(station: dict[str, Any]) -> str:
    pose = station["pose"]
    held = ", ".join(station["status"]["reservations"]) or "none"
    types = ", ".join(station["robot_types"]) or "any"
    return (
        f"**{station['name']}** ({station['kind']})\n"
        f"- Position: ({pose['x']:.2f}, {pose['y']:.2f}) on map {pose['map_id']!r}\n"
        f"- Robot types: {types}; capacity {station['capacity']}; held by: {held}\n"
    )


def robot_text(robot: dict[str, Any]) -> str:
    status = robot["status"]
    pose = status["pose"]
    lines = [
        f"**{robot['name']}**",
        f"- State: {status['state']}",
        f"- Online: {status['online']}",
        f"- Battery: {status['battery_level']:.1f}%",
        f"- Position: ({pose['x']:.2f}, {pose['y']:.2f}) on map {pose['map_id']!r}",
    ]
    if robot["switch_teleop"]:
        lines.append("- Teleop: requested")
    if status["errors"]:
        lines.append(f"- Errors: {_error_names(status['errors'])}")
    if robot["lifecycle"] != "ALIVE":
        lines.append(f"- Lifecycle: {robot['lifecycle']}")
    return "\n".join(lines) + "\n"


def _error_names(errors: Any) -> str:
    return ", ".join(errors) if isinstance(errors, dict) else str(errors)


def mission_text(mission: dict[str, Any]) -> str:
    status = mission["status"]
    robot = mission["robot"] or "none yet (unbound: assignment picks one)"
    lines = [f"**{mission['name']}**", f"- State: {status['state']}", f"- Robot: {robot}"]
    labels = {
        "start_timestamp": "Started",
        "end_timestamp": "Ended",
        "failure_reason": "Failure",
        "failure_category": "Failure category",
        "waiting_reason": "Waiting",
    }
    lines += [f"- {label}: {status[key]}" for key, label in labels.items() if status.get(key)]
    return "\n".join(lines) + "\n"


def _listing(title: str, items: list[dict[str, Any]], text: Callable[[dict], str], none: str) -> str:
    return f"**{title}**\n\n" + ("\n".join(text(item) for item in items) if items else f"{none}\n")


def _tree_text(mission: dict[str, Any]) -> str:
    """The mission tree, one node a line, indented under its parent, with each node's state."""
    node_status = mission["status"]["node_status"]
    children: dict[str, list[dict[str, Any]]] = {}
    for node in mission["mission_tree"]:
        children.setdefault(node["parent"], []).append(node)

    def lines(parent: str, depth: int) -> Iterable[str]:
        for node in children.get(parent, []):
            kind = next(kind for kind in NODE_KINDS if node.get(kind) is not None)
            status = node_status.get(node["name"], {})
            error = f" ({status['error_msg']})" if status.get("error_msg") else ""
            yield f"{'  ' * depth}- {node['name']} [{kind}]: {status.get('state', 'PENDING')}{error}"
            yield from lines(node["name"], depth + 1)

    root = node_status.get("root", {}).get("state", "PENDING")
    return "\n".join([f"- root [sequence]: {root}", *lines("root", 1)]) + "\n"


# --- the reference's tools ----------------------------------------------------------------------------


@tool(
    name="test_mission_dispatch_connection",
    description=(
        "Check that Mission Dispatch answers and this token works: the server's status, how many robots "
        "and missions it holds, and what the token may do (read only, or read and write)."
    ),
    annotations=READS,
)
def test_mission_dispatch_connection(caller: Any) -> Answer:
    data = {
        "status": HEALTH_STATUS,
        "robots": robot_list().count(),
        "missions": mission_list().count(),
        "token": caller.name,
        "read_only": caller.read_only,
    }
    text = (
        "**Mission Dispatch Connection OK**\n\n"
        f"- Status: {HEALTH_STATUS}\n- Robots: {data['robots']}\n- Missions: {data['missions']}\n"
        f"- Token: {caller.name} ({'read only' if caller.read_only else 'read and write'})\n"
    )
    return text, data


@tool(
    name="get_robot_status",
    description=(
        "Robots and their status (state, online, battery, position, errors): all of them, those in one "
        "state, or one robot by name."
    ),
    annotations=READS,
)
def get_robot_status(
    caller: Any,
    state: Annotated[RobotStateName | None, Field(description="Only robots in this state.")] = None,
    robot_name: Annotated[Name | None, Field(description="Only this robot (state is then ignored).")] = None,
) -> Answer:
    if robot_name:
        robot = api_json(RobotSerializer(robot_get(name=robot_name)).data)
        return f"**Robot {robot_name} Status**\n\n{robot_text(robot)}", {"robots": [robot]}
    robots = _robots(state=state)
    title = f"Robots in {state} state" if state else "All Robots"
    return _listing(title, robots, robot_text, "No robots found."), {"robots": robots}


@tool(
    name="get_mission_status",
    description=(
        "Missions and their status (state, robot, start and end, failure): all of them in submission "
        "order, or those in one state and/or of one robot. For one mission's tree use get_mission."
    ),
    annotations=READS,
)
def get_mission_status(
    caller: Any,
    state: Annotated[MissionStateName | None, Field(description="Only missions in this state.")] = None,
    robot: Annotated[Name | None, Field(description="Only missions of this robot.")] = None,
) -> Answer:
    missions = _missions(state=state, robot=robot)
    where = [f"in {state} state" if state else "", f"for robot {robot}" if robot else ""]
    title = " ".join(["Missions", *filter(None, where)]) if state or robot else "All Missions"
    return _listing(title, missions, mission_text, "No missions found."), {"missions": missions}


@tool(
    name="get_robots_on_missions",
    description="Robots busy with a mission (state ON_TASK), each with its running and queued missions.",
    annotations=READS,
)
def get_robots_on_missions(caller: Any) -> Answer:
    robots = _robots(state=RobotState.ON_TASK)
    missions = [mission for state in ACTIVE_STATES for mission in _missions(state=state)]
    text = "**Robots Currently On Missions**\n\n"
    if not robots:
        text += "No robots are currently on missions.\n"
    for robot in robots:
        active = [mission for mission in missions if mission["robot"] == robot["name"]]
        text += robot_text(robot)
        text += "".join(f"- Mission: {m['name']} ({m['status']['state']})\n" for m in active) + "\n"
    names = {robot["name"] for robot in robots}
    data = {"robots": robots, "missions": [mission for mission in missions if mission["robot"] in names]}
    return text, data


@tool(
    name="get_idle_robots",
    description="Robots that are idle (state IDLE), so available for a new mission, and how many are online.",
    annotations=READS,
)
def get_idle_robots(caller: Any) -> Answer:
    robots = _robots(state=RobotState.IDLE)
    text = _listing("Idle Robots Available for Missions", robots, robot_text, "No robots are currently idle.")
    if robots:
        online = sum(robot["status"]["online"] for robot in robots)
        text += f"\nSummary: {len(robots)} idle robots ({online} online)\n"
    return text, {"robots": robots}


@tool(
    name="list_stations",
    description="Chargers and parking stations: where each is, which robot types it serves, its capacity "
    "and the robots holding it.",
    annotations=READS,
)
def list_stations(
    caller: Any,
    kind: Annotated[StationKindName | None, Field(description="Only CHARGER or PARKING stations.")] = None,
) -> Answer:
    stations = api_json(StationSerializer(station_list(filters=_query(kind=kind)), many=True).data)
    return _listing("Stations", stations, station_text, "No stations."), {"stations": stations}


@tool(
    name="get_fleet_summary",
    description=(
        "A dashboard of the fleet: robots per state, online share and average battery; missions per state "
        "and how many are active (running or queued)."
    ),
    annotations=READS,
)
def get_fleet_summary(caller: Any) -> Answer:
    robots = _robots()
    batteries = [robot["status"]["battery_level"] for robot in robots if robot["status"]["battery_level"] > 0]
    robot_states = Counter(robot["status"]["state"] for robot in robots)
    mission_states = Counter(mission_list().order_by().values_list("state", flat=True))
    data = {
        "robots": {
            "total": len(robots),
            "by_state": dict(sorted(robot_states.items())),
            "online": sum(robot["status"]["online"] for robot in robots),
            "average_battery": sum(batteries) / len(batteries) if batteries else None,
        },
        "missions": {
            "total": sum(mission_states.values()),
            "by_state": dict(sorted(mission_states.items())),
            "active": sum(mission_states[state] for state in ACTIVE_STATES),
        },
    }
    text = "**Mission Dispatch Fleet Dashboard**\n\n## Robot Fleet Status\n"
    text += "".join(f"- {state}: {count} robots\n" for state, count in data["robots"]["by_state"].items())
    text += f"\nFleet summary:\n- Total robots: {len(robots)}\n"
    if robots:
        online = data["robots"]["online"]
        text += f"- Online: {online} ({100 * online / len(robots):.1f}%)\n"
    if batteries:
        text += f"- Average battery: {data['robots']['average_battery']:.1f}%\n"
    text += "\n## Mission Status\n"
    text += "".join(f"- {state}: {n} missions\n" for state, n in data["missions"]["by_state"].items())
    text += (
        f"\nMission summary:\n- Total missions: {data['missions']['total']}\n"
        f"- Currently active: {data['missions']['active']}\n"
    )
    return text, data


@tool(
    name="check_robot_health",
    description=(
        "Robots that need attention: offline, battery below a threshold (percent), or reporting errors; "
        "and how many are healthy."
    ),
    annotations=READS,
)
def check_robot_health(
    caller: Any,
    min_battery: Annotated[
        float, Field(ge=0, le=100, description="Battery percentage below which an online robot is low.")
    ] = DEFAULT_MIN_BATTERY,
) -> Answer:
    robots = _robots()
    offline = [r["name"] for r in robots if not r["status"]["online"]]
    low = {
        r["name"]: r["status"]["battery_level"]
        for r in robots
        if r["status"]["online"] and r["status"]["battery_level"] < min_battery
    }
    errors = {r["name"]: r["status"]["errors"] for r in robots if r["status"]["errors"]}
    healthy = [r["name"] for r in robots if r["name"] not in {*offline, *low, *errors}]
    text = "**Robot Health Check**\n\n"
    if offline:
        text += f"Offline robots ({len(offline)}):\n" + "".join(f"- {name}\n" for name in offline) + "\n"
    if low:
        text += f"Low battery robots (< {min_battery}%, {len(low)}):\n"
        text += "".join(f"- {name}: {battery:.1f}%\n" for name, battery in low.items()) + "\n"
    if errors:
        text += f"Robots with errors ({len(errors)}):\n"
        text += "".join(f"- {name}: {_error_names(value)}\n" for name, value in errors.items()) + "\n"
    if healthy:
        text += f"Healthy robots ({len(healthy)}):\n" + "".join(f"- {n}\n" for n in healthy[:HEALTHY_SHOWN])
        more = len(healthy) - HEALTHY_SHOWN
        text += (f"- ... and {more} more\n" if more > 0 else "") + "\n"
    issues = len(offline) + len(low) + len(errors)
    if not issues:
        text += "All robots are healthy.\n\n"
    text += f"Health summary:\n- Healthy: {len(healthy)}/{len(robots)}\n- Issues: {issues}\n"
    data = {
        "min_battery": min_battery,
        "offline": offline,
        "low_battery": low,
        "errors": errors,
        "healthy": healthy,
    }
    return text, data


@tool(
    name="get_mission_queue",
    description="Missions waiting to start (PENDING), in the order they will run, with why each waits.",
    annotations=READS,
)
def get_mission_queue(caller: Any) -> Answer:
    missions = _missions(state=MissionState.PENDING)
    text = _listing(
        "Mission Queue (Pending Missions)", missions, mission_text, "No missions currently pending."
    )
    return text, {"missions": missions}


@tool(
    name="get_recent_failures",
    description="Failed missions, newest first, with their failure reason and category.",
    annotations=READS,
)
def get_recent_failures(caller: Any) -> Answer:
    missions = _missions(state=MissionState.FAILED)[::-1]
    text = _listing("Recent Mission Failures", missions, mission_text, "No failed missions found.")
    return text, {"missions": missions}


@tool(
    name="create_robot",
    description=(
        "Add a robot to the fleet (as POST /robot with the default spec). Its name is its VDA 5050 serial "
        "number; it shows up online once the robot connects."
    ),
    annotations=WRITES,
)
def create_robot(
    caller: Any,
    name: Annotated[Name, Field(description="The robot's name, unique in the fleet.")],
    labels: Annotated[
        list[str] | None, Field(description='Free labels of the robot, e.g. ["forklift"].')
    ] = None,
) -> Answer:
    spec = body_validated(RobotCreateSerializer, {"name": name, **({"labels": labels} if labels else {})})
    robot = robot_create(actor=caller.actor, name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec)
    data = api_json(RobotSerializer(robot).data)
    return f"**Robot Created Successfully**\n\n{robot_text(data)}", data


@tool(
    name="dispatch_mission",
    description=(
        "Send a robot to a point: a mission with one route to (x, y) facing theta, queued behind the "
        "robot's other missions. Returns the mission; follow it with get_mission."
    ),
    annotations=WRITES,
)
def dispatch_mission(
    caller: Any,
    robot: Annotated[Name, Field(description="The robot to send.")],
    x: Annotated[float, Field(description="Target x coordinate, metres.")],
    y: Annotated[float, Field(description="Target y coordinate, metres.")],
    theta: Annotated[float, Field(description="Orientation at the target, radians.")] = 0.0,
    mission_name: Annotated[
        Name | None, Field(description="Name of the mission; default: move_to_<x>_<y>-<random id>.")
    ] = None,
    map_id: Annotated[
        str | None, Field(description="Map of the point; default: the map the robot is on.")
    ] = None,
) -> Answer:
    if map_id is None:
        known = robot_list(filters=_query(names=robot)).first()
        point_map = known.pose_map_id if known is not None and known.pose_map_id else ""
    else:
        point_map = map_id
    target = f"move_to_{x:.2f}_{y:.2f}"
    body = {
        "robot": robot,
        "mission_tree": [
            {
                "name": target,
                "route": {"waypoints": [{"x": x, "y": y, "theta": theta, "map_id": point_map}]},
            }
        ],
        **({"name": mission_name} if mission_name else {"prefix": target}),
    }
    mission = _mission_create(caller, body)
    text = f"**Mission Dispatched Successfully**\n\n{mission_text(mission)}"
    return text + f"\nTarget: ({x:.2f}, {y:.2f}) @ {theta:.2f} rad\n", mission


def _mission_create(caller: Any, body: dict[str, Any]) -> dict[str, Any]:
    """POST /mission's path: the body validated as the view validates it, then the service."""
    spec = body_validated(MissionCreateSerializer, body)
    mission = mission_create(actor=caller.actor, name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec)
    return api_json(MissionSerializer(mission).data)


# --- beyond the reference -------------------------------------------------------------------------------


@tool(
    name="get_mission",
    description=(
        "One mission in full: its state, robot, failure or waiting reason, and its tree with each node's "
        "state (which node is running, which failed and why)."
    ),
    annotations=READS,
)
def get_mission(caller: Any, name: Annotated[Name, Field(description="The mission's name.")]) -> Answer:
    mission = api_json(MissionSerializer(mission_get(name=name)).data)
    return f"{mission_text(mission)}\nTree:\n{_tree_text(mission)}", mission


@tool(
    name="create_mission",
    description=(
        "Submit any mission, exactly as POST /mission: a behaviour tree (mission_tree) for a robot. Each "
        'node has a name, a parent ("root" or an earlier sequence/selector) and exactly one kind: route '
        "(waypoints), move, action (VDA 5050 action_type and action_parameters), notify (an HTTP call), "
        "constant, sequence (children in order, fails at the first failure) or selector (children in order "
        "until one succeeds). For a plain trip to one point, dispatch_mission is simpler."
    ),
    annotations=WRITES,
)
def create_mission(
    caller: Any,
    mission_tree: Any,
    robot: Any = None,
    name: Any = None,
    prefix: Any = None,
    timeout: Any = None,
    deadline: Any = None,
    needs_canceled: Any = None,
    update_nodes: Any = None,
    priority: Any = None,
    robot_selector: Any = None,
) -> Answer:
    # Untyped here: the arguments are POST /mission's body, validated by its serializer alone (the
    # advertised schema is the API's, `create_mission_schema`). An argument sent as null is left out.
    arguments = {
        "robot": robot,
        "mission_tree": mission_tree,
        "name": name,
        "prefix": prefix,
        "timeout": timeout,
        "deadline": deadline,
        "needs_canceled": needs_canceled,
        "update_nodes": update_nodes,
        "priority": priority,
        "robot_selector": robot_selector,
    }
    mission = _mission_create(caller, {key: value for key, value in arguments.items() if value is not None})
    return f"**Mission Created**\n\n{mission_text(mission)}\nTree:\n{_tree_text(mission)}", mission


@cache
def create_mission_schema() -> dict[str, Any]:
    """create_mission's input schema: POST /mission's body as the API's OpenAPI schema states it (every
    node kind, bound and default), the components it uses as $defs, OpenAPI's `nullable` as JSON Schema's
    null type."""
    from drf_spectacular.generators import SchemaGenerator

    components = SchemaGenerator().get_schema(request=None, public=True)["components"]["schemas"]
    definitions = _json_schema(json.loads(json.dumps(components).replace(REF_OPENAPI, REF_JSON_SCHEMA)))
    used, todo = set(), ["MissionCreateRequest"]
    while todo:
        name = todo.pop()
        if name not in used:
            used.add(name)
            todo += re.findall(rf'"{re.escape(REF_JSON_SCHEMA)}(\w+)"', json.dumps(definitions[name]))
    schema = definitions["MissionCreateRequest"]
    return {**schema, "$defs": {name: definitions[name] for name in sorted(used - {"MissionCreateRequest"})}}


REF_OPENAPI, REF_JSON_SCHEMA = "#/components/schemas/", "#/$defs/"


def _json_schema(node: Any) -> Any:
    if isinstance(node, list):
        return [_json_schema(item) for item in node]
    if not isinstance(node, dict):
        return node
    converted = {key: _json_schema(value) for key, value in node.items() if key != "nullable"}
    if node.get("nullable") and "type" in node:
        converted["type"] = [node["type"], "null"]
    elif node.get("nullable"):
        converted = {"anyOf": [converted, {"type": "null"}]}
    return converted


@tool(
    name="cancel_mission",
    description=(
        "Cancel a mission: a queued one is CANCELED at once; a running one is stopped by the robot "
        "(cancelOrder) and becomes CANCELED when the robot confirms. A finished mission cannot be canceled."
    ),
    annotations=STOPS,
)
def cancel_mission(caller: Any, name: Annotated[Name, Field(description="The mission's name.")]) -> Answer:
    mission = mission_cancel(actor=caller.actor, mission=mission_get(name=name))
    data = api_json(MissionSerializer(mission).data)
    return f"Mission {name} will be canceled.\n\n{mission_text(data)}", data


def _teleop(caller: Any, robot: str, action: TeleopAction) -> Answer:
    changed = robot_teleop(actor=caller.actor, robot=robot_get(name=robot), action=action)
    data = api_json(RobotSerializer(changed).data)
    return f"{action} teleop action received.\n\n{robot_text(data)}", data


@tool(
    name="start_teleop",
    description=(
        "Put a robot in teleoperation (VDA 5050 startTeleop): it stops following missions until stop_teleop. "
        "Allowed when the robot is IDLE, ON_TASK, MAP_DEPLOYMENT or TELEOP."
    ),
    annotations=WRITES,
)
def start_teleop(caller: Any, robot: Annotated[Name, Field(description="The robot.")]) -> Answer:
    return _teleop(caller, robot, TeleopAction.START)


@tool(
    name="stop_teleop",
    description="Take a robot out of teleoperation (VDA 5050 stopTeleop); its mission goes on.",
    annotations=WRITES,
)
def stop_teleop(caller: Any, robot: Annotated[Name, Field(description="The robot.")]) -> Answer:
    return _teleop(caller, robot, TeleopAction.STOP)


@tool(
    name="update_route",
    description=(
        "Give a route node of a queued or running mission new waypoints (as POST /mission/{name}/update); "
        "a node already done cannot be changed. Each waypoint: x, y, theta (radians), map_id."
    ),
    annotations=WRITES,
)
def update_route(
    caller: Any,
    mission: Annotated[Name, Field(description="The mission's name.")],
    node: Annotated[Name, Field(description="The route node's name in the mission tree.")],
    waypoints: Annotated[
        list[dict[str, Any]],
        Field(description='The new waypoints, e.g. [{"x": 1.5, "y": 2.0, "theta": 0, "map_id": "map"}].'),
    ],
) -> Answer:
    update_nodes = RouteUpdatesField().run_validation({node: {"waypoints": waypoints}})
    mission_update_routes(actor=caller.actor, mission=mission_get(name=mission), update_nodes=update_nodes)
    data = api_json(RouteUpdatesField().to_representation(update_nodes))
    points = ", ".join(f"({p['x']:.2f}, {p['y']:.2f})" for p in data[node]["waypoints"])
    return f"Route {node} of mission {mission} updated: {points}\n", data
