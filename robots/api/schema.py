"""The OpenAPI documentation of the robot endpoints, one `extend_schema` keyword set per operation (the
views apply them): summaries, descriptions, bodies, responses and examples."""

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiExample, OpenApiResponse

from kit.api.schema import DETAIL_RESPONSE, SCHEMA_ERROR_EXAMPLE, bad_request
from robots.api.serializers import (
    MapActionRequestSerializer,
    MapActionSerializer,
    RobotCreateSerializer,
    RobotMapsSerializer,
    RobotSerializer,
    RobotSpecSerializer,
    TeleopQuerySerializer,
)
from vda5050.orders import DEFAULT_ALLOWED_DEVIATION_THETA, DEFAULT_ALLOWED_DEVIATION_XY

README_ROBOT = {"labels": [], "battery": {"critical_level": 0.1}, "heartbeat_timeout": 30, "name": "carter01"}
ROBOT_EXAMPLE = OpenApiExample(
    "carter01",
    response_only=True,
    value={
        "labels": [],
        "battery": {"critical_level": 0.1, "recommended_minimum": None, "recommended_maximum": None},
        "heartbeat_timeout": 30.0,
        "switch_teleop": False,
        "vda5050": {
            "interface_name": "uagv",
            "manufacturer": "RobotCompany",
            "serial_number": "carter01",
            "version": "2.0.0",
            "version_source": "DEFAULT",
            "instant_actions_key": "actions",
            "instant_actions_key_source": "DEFAULT",
            "compatibility_rules": [],
        },
        "name": "carter01",
        "status": {
            "pose": {
                "x": 4.0,
                "y": 5.0,
                "theta": 0.0,
                "map_id": "map",
                "allowedDeviationXY": DEFAULT_ALLOWED_DEVIATION_XY,
                "allowedDeviationTheta": DEFAULT_ALLOWED_DEVIATION_THETA,
            },
            "position_initialized": True,
            "software_version": {"os": "", "app": ""},
            "hardware_version": {"manufacturer": "RobotCompany", "serial_number": "carter01"},
            "factsheet": {"agv_class": "CARRIER", "speed_max": 1.0},
            "online": True,
            "battery_level": 42.0,
            "state": "IDLE",
            "info_messages": None,
            "errors": {},
            "maps": [],
            "zone_access": {"held": [], "waiting": []},
            "charge_requested": False,
            "charging_waiting_reason": None,
        },
        "lifecycle": "ALIVE",
    },
)
NOT_FOUND_EXAMPLE = OpenApiExample(
    "Robot not found", value={"detail": 'Did not find "robot" with name "carter99"'}, status_codes=["400"]
)
NOT_FOUND_TO_CHANGE_EXAMPLE = OpenApiExample(
    "Robot not found", value={"detail": "Could not find object carter99"}, status_codes=["400"]
)
MAP_ACTION_EXAMPLE = OpenApiExample(
    "downloadMap",
    response_only=True,
    value={
        "action_id": "carter01-downloadMap-0b7e4a52-7d0e-4f4a-9c56-3f1f0c1d2e11",
        "action": "downloadMap",
        "parameters": {
            "mapId": "warehouse",
            "mapVersion": "2",
            "mapDownloadLink": "https://maps.example/warehouse/2",
        },
        "status": None,
        "sent_at": None,
        "created_at": "2026-11-26T15:00:00Z",
    },
)
NO_MAPS_EXAMPLE = OpenApiExample(
    "VDA 5050 2.0 robot",
    value={
        "message": "Robot carter01 speaks VDA 5050 2.0.0, which has no map actions (maps came with 2.1.0).",
        "error_code": "USAGE",
    },
    status_codes=["400"],
)
DELETED_EXAMPLE = OpenApiExample("Deleted", value={"detail": "carter01 is PENDING_DELETE"})


ROBOT_LIST = dict(
    operation_id="robot_list",
    summary="List robots",
    description="All robots, ordered by name, narrowed by the filters (combined with AND).",
    responses={200: RobotSerializer(many=True), 400: bad_request(SCHEMA_ERROR_EXAMPLE)},
    examples=[ROBOT_EXAMPLE],
)

ROBOT_CREATE = dict(
    operation_id="robot_create",
    summary="Create a robot",
    description=(
        "Creates a robot. Without a name or prefix it gets a random id as name. The robot's name is its "
        "VDA 5050 serial number unless vda5050.serial_number says otherwise."
    ),
    request=RobotCreateSerializer,
    responses={
        200: RobotSerializer,
        400: bad_request(
            OpenApiExample(
                "Duplicate",
                value={"detail": "Object robot with name carter01 already exists"},
                status_codes=["400"],
            ),
            SCHEMA_ERROR_EXAMPLE,
        ),
    },
    examples=[OpenApiExample("README robot", value=README_ROBOT, request_only=True), ROBOT_EXAMPLE],
)

ROBOT_GET = dict(
    operation_id="robot_get",
    summary="Get a robot",
    responses={200: RobotSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[ROBOT_EXAMPLE],
)

ROBOT_UPDATE = dict(
    operation_id="robot_update",
    summary="Replace a robot's spec",
    description="Replaces the whole spec: fields the body omits go back to their defaults.",
    request=RobotSpecSerializer,
    responses={200: RobotSerializer, 400: bad_request(NOT_FOUND_TO_CHANGE_EXAMPLE, SCHEMA_ERROR_EXAMPLE)},
    examples=[
        OpenApiExample(
            "Shorter heartbeat",
            value={"labels": ["warehouse"], "heartbeat_timeout": 10},
            request_only=True,
        ),
        ROBOT_EXAMPLE,
    ],
)

ROBOT_DELETE = dict(
    operation_id="robot_delete",
    summary="Delete a robot",
    description=(
        "Marks the robot PENDING_DELETE. It is removed at once, or, if it is running a mission, once the "
        "dispatch engine has failed that mission."
    ),
    responses={200: DETAIL_RESPONSE, 400: bad_request(NOT_FOUND_TO_CHANGE_EXAMPLE)},
    examples=[DELETED_EXAMPLE],
)

ROBOT_TELEOP = dict(
    operation_id="robot_teleop",
    summary="Start or stop teleop",
    description=(
        "START puts the robot in teleop (allowed when it is IDLE, ON_TASK, MAP_DEPLOYMENT or TELEOP); "
        "STOP takes it out. The dispatch engine sends the robot startTeleop or stopTeleop."
    ),
    request=None,
    parameters=[TeleopQuerySerializer],
    responses={
        200: OpenApiResponse(
            OpenApiTypes.STR,
            examples=[OpenApiExample("START", value="START teleop action received.")],
        ),
        400: bad_request(
            NOT_FOUND_EXAMPLE,
            OpenApiExample(
                "Not allowed",
                value={
                    "message": "Robot carter01 is in CHARGING and request cannot be satisfied: "
                    "teleop can only start from IDLE, MAP_DEPLOYMENT, ON_TASK, TELEOP.",
                    "error_code": "USAGE",
                },
                status_codes=["400"],
            ),
        ),
    },
    filters=False,
)

ROBOT_CHARGE = dict(
    operation_id="robot_charge",
    summary="Send a robot to charge now",
    description=(
        'Whatever its battery, the robot is sent to the nearest free charger it may use (README "Stations: '
        'charging and parking"): the charger is reserved for it, then a CHARGE mission goes ahead of its '
        "queue (after its running mission, if any). Until then status.charging_waiting_reason says why it "
        "waits (no free charger, ...). Refused for a robot offline, charging already, or whose factsheet "
        "lists no startCharging."
    ),
    request=None,
    responses={
        200: OpenApiResponse(RobotSerializer, examples=[ROBOT_EXAMPLE]),
        400: bad_request(
            NOT_FOUND_EXAMPLE,
            OpenApiExample(
                "Cannot charge",
                value={
                    "message": "Robot carter01 cannot be sent to charge: its factsheet lists no "
                    "startCharging.",
                    "error_code": "USAGE",
                },
                status_codes=["400"],
            ),
        ),
    },
    filters=False,
)

ROBOT_MAPS = dict(
    methods=["GET"],
    operation_id="robot_maps",
    summary="A robot's maps and map actions",
    description=(
        "The maps the robot reports (VDA 5050 2.1+ state.maps) and the map actions asked of it, newest "
        "first, each with the status the robot last reported."
    ),
    responses={200: RobotMapsSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[
        OpenApiExample(
            "A map downloaded and enabled",
            response_only=True,
            value={
                "maps": [
                    {
                        "map_id": "warehouse",
                        "map_version": "2",
                        "map_status": "ENABLED",
                        "map_description": None,
                    }
                ],
                "actions": [{**MAP_ACTION_EXAMPLE.value, "status": "FINISHED"}],
            },
        )
    ],
    filters=False,
)

ROBOT_MAP_ACTION = dict(
    methods=["POST"],
    operation_id="robot_map_action",
    summary="Download, enable or delete a map",
    description=(
        "Asks the robot (VDA 5050 2.1 or later) to download a map version (downloadMap), enable it "
        "(enableMap) or delete it (deleteMap). The dispatch engine sends it as an instant action and "
        "tracks it until the robot reports it FINISHED or FAILED (GET /robot/{name}/map). A mission "
        "whose waypoints name a map the robot does not report ENABLED waits for it."
    ),
    request=MapActionRequestSerializer,
    responses={
        200: MapActionSerializer,
        400: bad_request(NOT_FOUND_EXAMPLE, NO_MAPS_EXAMPLE, SCHEMA_ERROR_EXAMPLE),
    },
    examples=[
        OpenApiExample(
            "Download",
            request_only=True,
            value={
                "action": "downloadMap",
                "map_id": "warehouse",
                "map_version": "2",
                "map_download_link": "https://maps.example/warehouse/2",
            },
        ),
        OpenApiExample(
            "Enable",
            request_only=True,
            value={"action": "enableMap", "map_id": "warehouse", "map_version": "2"},
        ),
        MAP_ACTION_EXAMPLE,
    ],
    filters=False,
)
