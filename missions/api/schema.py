"""The OpenAPI documentation of the mission endpoints and GET /behaviors, one `extend_schema` keyword set per
operation (the views apply them): summaries, descriptions, bodies, responses and examples."""

from drf_spectacular.utils import OpenApiExample, inline_serializer
from rest_framework import serializers

from dispatch.vocabulary import NodeKind
from kit.api.schema import DETAIL_RESPONSE, SCHEMA_ERROR_EXAMPLE, bad_request
from missions.api.serializers import MissionCreateSerializer, MissionSerializer, node_description
from vda5050.orders import DEFAULT_ALLOWED_DEVIATION_THETA, DEFAULT_ALLOWED_DEVIATION_XY


def _waypoint(x: float, y: float) -> dict:
    return {"x": x, "y": y, "theta": 0, "map_id": "map"}


def _route(name: str, *waypoints: dict, parent: str = "root") -> dict:
    return {"name": name, "parent": parent, "route": {"waypoints": list(waypoints)}}


def _dummy_action(name: str, *, should_fail: int, parent: str = "root") -> dict:
    parameters = {"should_fail": should_fail, "time": 1}
    return {
        "name": name,
        "parent": parent,
        "action": {"action_type": "dummy_action", "action_parameters": parameters},
    }


def _readme_mission(name: str, deadline: str, *mission_tree: dict) -> dict:
    return {
        "robot": "carter01",
        "mission_tree": list(mission_tree),
        "timeout": 300,
        "deadline": deadline,
        "needs_canceled": False,
        "name": name,
    }


# The README's three example missions.
README_MISSIONS = {
    "simple_mission_example": _readme_mission(
        "simple_mission_example",
        "2023-09-28T04:04:24.013Z",
        _route("goto_pickup", _waypoint(1.5, 1.5), _waypoint(3.3, 2.1)),
        _route("goto_dropoff", _waypoint(4.0, 3.2), _waypoint(5.0, 5.0)),
    ),
    "complex_mission_example": _readme_mission(
        "complex_mission_example",
        "2023-09-28T04:04:24.013Z",
        _route("goto_pickup", _waypoint(1.5, 0.8)),
        _dummy_action("pickup_book", should_fail=0),
        {"name": "route_fallback", "parent": "root", "selector": {}},
        _route("goto_dropoff", _waypoint(3, 2.2), _waypoint(0.8, 1.8), parent="route_fallback"),
        {"name": "goto_dropoff_seq", "parent": "route_fallback", "sequence": {}},
        _route("reset_pose", _waypoint(1.5, 0.8), parent="goto_dropoff_seq"),
        _dummy_action("dropoff_book", should_fail=1, parent="goto_dropoff_seq"),
        _dummy_action("dropoff_book_at_goal", should_fail=1),
    ),
    "mission_with_teleop": _readme_mission(
        "mission_with_teleop",
        "2023-11-01T00:21:31.112Z",
        _route("goto_pickup", _waypoint(5, 0)),
        {
            "name": "forklift_teleop",
            "parent": "root",
            "action": {"action_type": "pause_order", "action_parameters": {}},
        },
        _route("goto_dropoff", _waypoint(0, 0)),
    ),
}
# A mission posted without a robot: any robot carrying the label and listing the action type may take it.
UNBOUND_MISSION = {
    "robot_selector": {"labels": ["forklift"], "robot_types": [], "action_types": ["dummy_action"]},
    "priority": 10,
    "mission_tree": [
        _route("goto_pickup", _waypoint(1.5, 0.8)),
        _dummy_action("pickup_pallet", should_fail=0),
    ],
    "name": "unbound_mission_example",
}
MISSION_EXAMPLE = OpenApiExample(
    "A running mission",
    response_only=True,
    value={
        "robot": "carter01",
        "mission_tree": [
            {
                "name": "goto_pickup",
                "parent": "root",
                "selector": None,
                "sequence": None,
                "route": {
                    "waypoints": [
                        {
                            "x": 1.5,
                            "y": 1.5,
                            "theta": 0.0,
                            "map_id": "map",
                            "allowedDeviationXY": DEFAULT_ALLOWED_DEVIATION_XY,
                            "allowedDeviationTheta": DEFAULT_ALLOWED_DEVIATION_THETA,
                        }
                    ]
                },
                "move": None,
                "action": None,
                "notify": None,
                "constant": None,
            }
        ],
        "timeout": 300.0,
        "deadline": None,
        "needs_canceled": False,
        "update_nodes": None,
        "priority": 0,
        "robot_selector": None,
        "name": "simple_mission_example",
        "status": {
            "state": "RUNNING",
            "current_node": 0,
            "node_status": {
                "root": {"state": "RUNNING", "error_msg": None},
                "goto_pickup": {"state": "RUNNING", "error_msg": None},
            },
            "task_status": {},
            "start_timestamp": "2023-09-28T04:00:00.000000Z",
            "end_timestamp": None,
            "failure_reason": None,
            "failure_category": None,
            "waiting_reason": None,
            "assignment": [],
        },
        "lifecycle": "ALIVE",
    },
)
NOT_FOUND_EXAMPLE = OpenApiExample(
    "Mission not found",
    value={"detail": 'Did not find "mission" with name "mission99"'},
    status_codes=["400"],
)
USAGE_EXAMPLE = OpenApiExample(
    "Not allowed",
    value={"message": "Completed mission simple_mission_example can't be canceled.", "error_code": "USAGE"},
    status_codes=["400"],
)
ROUTE_UPDATE = {"goto_dropoff": {"waypoints": [_waypoint(4.5, 3.0)]}}


def _route_updates_schema(route_node_component: str) -> dict:
    """Schema of a RouteUpdatesField body (drf-spectacular documents bare fields only inside serializers)."""
    return {
        "type": "object",
        "additionalProperties": {"$ref": f"#/components/schemas/{route_node_component}"},
        "description": "New waypoints per route node name.",
    }


MISSION_LIST = dict(
    operation_id="mission_list",
    summary="List missions",
    description=(
        "All missions in submission order (most_recent: newest start first), narrowed by the filters "
        "(combined with AND). unbound=true lists the missions waiting for assignment; robot=NAME those of "
        "a robot, those assignment bound to it included."
    ),
    responses={200: MissionSerializer(many=True), 400: bad_request(SCHEMA_ERROR_EXAMPLE)},
    examples=[MISSION_EXAMPLE],
)

MISSION_CREATE = dict(
    operation_id="mission_create",
    summary="Submit a mission",
    description=(
        "Queues a mission for a robot (which need not exist yet); a robot runs its missions one after "
        "another, the highest priority first, in submission order among equals (a running mission is "
        "never preempted). Without a robot the mission is unbound: the dispatcher binds it to a free "
        "capable robot (online, idle, charged above its critical level, not in teleop, meeting "
        "robot_selector, the mission's maps enabled) when one is free, the nearest to its first waypoint "
        "first, and its robot field then holds that robot's name; until then robot is null and "
        "status.waiting_reason says why it waits. Without a name or prefix the mission gets a random id "
        "as name."
    ),
    request=MissionCreateSerializer,
    responses={
        200: MissionSerializer,
        400: bad_request(
            OpenApiExample(
                "A selector beside a robot",
                value={
                    "detail": [
                        {
                            "loc": ["body", "robot_selector"],
                            "msg": "Only a mission without robot has a robot_selector.",
                            "type": "selector_with_robot",
                        }
                    ]
                },
                status_codes=["400"],
            ),
            OpenApiExample(
                "Invalid tree",
                value={
                    "message": "MissionNode name goto_pickup is repeated. "
                    "All MissionNode names must be unique.",
                    "error_code": "USAGE",
                },
                status_codes=["400"],
            ),
            SCHEMA_ERROR_EXAMPLE,
        ),
    },
    examples=[
        *(OpenApiExample(name, value=body, request_only=True) for name, body in README_MISSIONS.items()),
        OpenApiExample("unbound_mission_example", value=UNBOUND_MISSION, request_only=True),
        MISSION_EXAMPLE,
    ],
)

MISSION_GET = dict(
    operation_id="mission_get",
    summary="Get a mission",
    responses={200: MissionSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[MISSION_EXAMPLE],
)

MISSION_DELETE = dict(
    operation_id="mission_delete",
    summary="Delete a mission",
    description=(
        "Marks the mission PENDING_DELETE. It is removed at once unless it is RUNNING: then it is "
        "canceled, and removed when it has ended."
    ),
    responses={
        200: DETAIL_RESPONSE,
        400: bad_request(
            OpenApiExample(
                "Mission not found",
                value={"detail": "Could not find object mission99"},
                status_codes=["400"],
            )
        ),
    },
    examples=[OpenApiExample("Deleted", value={"detail": "simple_mission_example is PENDING_DELETE"})],
)

MISSION_CANCEL = dict(
    operation_id="mission_cancel",
    summary="Cancel a mission",
    description=(
        "A queued mission is CANCELED at once. A running one is canceled by the robot (cancelOrder) and "
        "becomes CANCELED when the robot confirms. A finished mission cannot be canceled."
    ),
    request=None,
    responses={
        200: DETAIL_RESPONSE,
        400: bad_request(NOT_FOUND_EXAMPLE, USAGE_EXAMPLE),
    },
    examples=[
        OpenApiExample("Canceled", value={"detail": "Mission simple_mission_example will be canceled."})
    ],
    filters=False,
)

MISSION_UPDATE = dict(
    operation_id="mission_update",
    summary="Give route nodes new waypoints",
    description=(
        "Replaces the waypoints of route nodes, by node name, while the mission is PENDING or RUNNING; a "
        "node that is already done cannot be updated. Returns the updates with defaults applied. To "
        "change anything else, cancel the mission and submit a new one."
    ),
    request={"application/json": _route_updates_schema("RouteNodeRequest")},
    responses={
        200: _route_updates_schema("RouteNode"),
        400: bad_request(NOT_FOUND_EXAMPLE, SCHEMA_ERROR_EXAMPLE),
    },
    examples=[OpenApiExample("New drop-off", value=ROUTE_UPDATE, request_only=True)],
    filters=False,
)

BEHAVIORS = dict(
    operation_id="behaviors",
    summary="List the node kinds of mission trees",
    tags=["behaviors"],
    responses=inline_serializer(
        "Behavior",
        {
            "name": serializers.CharField(),
            "params": serializers.ListField(child=serializers.CharField()),
            "description": serializers.CharField(),
        },
        many=True,
    ),
    examples=[
        OpenApiExample(
            "Node kinds",
            value=[
                {
                    "name": NodeKind.CONSTANT,
                    "params": ["success"],
                    "description": node_description(NodeKind.CONSTANT),
                }
            ],
        )
    ],
)
