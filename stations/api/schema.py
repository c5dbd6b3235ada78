"""The OpenAPI documentation of the station endpoints, one `extend_schema` keyword set per operation."""

from drf_spectacular.utils import OpenApiExample

from kit.api.schema import DETAIL_RESPONSE, SCHEMA_ERROR_EXAMPLE, bad_request
from stations.api.serializers import StationCreateSerializer, StationSerializer, StationSpecSerializer

README_STATION = {
    "name": "charger01",
    "kind": "CHARGER",
    "pose": {"x": 1.0, "y": 2.0, "theta": 0.0, "map_id": "map"},
}
STATION_EXAMPLE = OpenApiExample(
    "charger01",
    response_only=True,
    value={
        "kind": "CHARGER",
        "pose": {"x": 1.0, "y": 2.0, "theta": 0.0, "map_id": "map"},
        "robot_types": [],
        "capacity": 1,
        "name": "charger01",
        "status": {"reservations": []},
        "lifecycle": "ALIVE",
    },
)
NOT_FOUND_EXAMPLE = OpenApiExample(
    "Station not found",
    value={"detail": 'Did not find "station" with name "charger99"'},
    status_codes=["400"],
)
NOT_FOUND_TO_CHANGE_EXAMPLE = OpenApiExample(
    "Station not found", value={"detail": "Could not find object charger99"}, status_codes=["400"]
)
HELD_EXAMPLE = OpenApiExample(
    "Held by a robot",
    value={
        "message": "Station charger01 is held by carter01: it can be deleted once they have left it.",
        "error_code": "USAGE",
    },
    status_codes=["400"],
)

STATION_LIST = dict(
    operation_id="station_list",
    summary="List stations",
    description="All stations, ordered by name, narrowed by the filters (combined with AND).",
    responses={200: StationSerializer(many=True), 400: bad_request(SCHEMA_ERROR_EXAMPLE)},
    examples=[STATION_EXAMPLE],
)

STATION_CREATE = dict(
    operation_id="station_create",
    summary="Create a station",
    description=(
        "Creates a charger or a parking station. Without a name or prefix it gets a random id as name."
    ),
    request=StationCreateSerializer,
    responses={
        200: StationSerializer,
        400: bad_request(
            OpenApiExample(
                "Duplicate",
                value={"detail": "Object station with name charger01 already exists"},
                status_codes=["400"],
            ),
            SCHEMA_ERROR_EXAMPLE,
        ),
    },
    examples=[OpenApiExample("README charger", value=README_STATION, request_only=True), STATION_EXAMPLE],
)

STATION_GET = dict(
    operation_id="station_get",
    summary="Get a station",
    responses={200: StationSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[STATION_EXAMPLE],
)

STATION_UPDATE = dict(
    operation_id="station_update",
    summary="Replace a station's spec",
    description=(
        "Replaces the whole spec: fields the body omits go back to their defaults. The capacity cannot "
        "fall below the robots holding the station."
    ),
    request=StationSpecSerializer,
    responses={
        200: StationSerializer,
        400: bad_request(NOT_FOUND_TO_CHANGE_EXAMPLE, HELD_EXAMPLE, SCHEMA_ERROR_EXAMPLE),
    },
    examples=[
        OpenApiExample(
            "Two carriers at a time",
            value={
                **{k: v for k, v in README_STATION.items() if k != "name"},
                "robot_types": ["CARRIER"],
                "capacity": 2,
            },
            request_only=True,
        ),
        STATION_EXAMPLE,
    ],
)

STATION_DELETE = dict(
    operation_id="station_delete",
    summary="Delete a station",
    description="Deletes the station at once, unless robots hold or reserve it.",
    responses={200: DETAIL_RESPONSE, 400: bad_request(NOT_FOUND_TO_CHANGE_EXAMPLE, HELD_EXAMPLE)},
    examples=[OpenApiExample("Deleted", value={"detail": "charger01 is DELETED"})],
)
