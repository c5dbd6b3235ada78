"""The OpenAPI documentation of the zone set endpoints, one `extend_schema` keyword set per operation."""

from drf_spectacular.utils import OpenApiExample

from kit.api.schema import DETAIL_RESPONSE, SCHEMA_ERROR_EXAMPLE, bad_request
from zones.api.serializers import ZoneGrantRevokeSerializer, ZoneSetCreateSerializer, ZoneSetSerializer

AISLE = {
    "zone_id": "aisle1",
    "zone_type": "RELEASE",
    "description": "Narrow aisle: one robot at a time",
    "vertices": [{"x": 2.0, "y": 0.0}, {"x": 3.0, "y": 0.0}, {"x": 3.0, "y": 6.0}, {"x": 2.0, "y": 6.0}],
    "release_loss_behavior": "STOP",
    "capacity": 1,
}
SLOW = {
    "zone_id": "dock-slow",
    "zone_type": "SPEED_LIMIT",
    "description": "",
    "vertices": [{"x": 6.0, "y": 6.0}, {"x": 9.0, "y": 6.0}, {"x": 9.0, "y": 9.0}],
    "maximum_speed": 0.3,
}
README_ZONE_SET = {"name": "floor1-v1", "map_id": "map", "description": "Floor 1", "zones": [AISLE, SLOW]}
ZONE_SET_EXAMPLE = OpenApiExample(
    "floor1-v1",
    response_only=True,
    value={
        "map_id": "map",
        "description": "Floor 1",
        "zones": [AISLE, SLOW],
        "name": "floor1-v1",
        "status": {"enabled": True},
        "lifecycle": "ALIVE",
    },
)
NOT_FOUND_EXAMPLE = OpenApiExample(
    "Zone set not found",
    value={"detail": 'Did not find "zone_set" with name "floor9"'},
    status_codes=["400"],
)
NOT_FOUND_TO_CHANGE_EXAMPLE = OpenApiExample(
    "Zone set not found", value={"detail": "Could not find object floor9"}, status_codes=["400"]
)
ENABLED_EXAMPLE = OpenApiExample(
    "Enabled",
    value={
        "message": "Zone set floor1-v1 is enabled on map map: disable it or enable another set of the map "
        "before deleting it.",
        "error_code": "USAGE",
    },
    status_codes=["400"],
)
POLYGON_EXAMPLE = OpenApiExample(
    "Polygon crossing itself",
    value={
        "detail": [
            {
                "loc": ["body", "zones", 0, "vertices"],
                "msg": "Edges 0 and 2 cross: the polygon must not intersect itself.",
                "type": "invalid_polygon",
            }
        ]
    },
    status_codes=["400"],
)

ZONE_SET_LIST = dict(
    operation_id="zone_set_list",
    summary="List zone sets",
    description="All zone sets, ordered by name, narrowed by the filters (combined with AND).",
    responses={200: ZoneSetSerializer(many=True), 400: bad_request(SCHEMA_ERROR_EXAMPLE)},
    examples=[ZONE_SET_EXAMPLE],
)

ZONE_SET_CREATE = dict(
    operation_id="zone_set_create",
    summary="Create a zone set",
    description=(
        "Creates a VDA 5050 3.0 zone set of a map, disabled. Its name is the zoneSetId; without a name or "
        "prefix it gets a random id. A zone set cannot be changed (VDA 5050: a zoneSetId's content is "
        "immutable): create a new one and enable it. Each zone is a counter-clockwise polygon that does "
        "not cross itself, with the fields its zone_type requires (RELEASE: release_loss_behavior, and "
        "our capacity; SPEED_LIMIT: maximum_speed; ACTION: entry_actions, during_actions, exit_actions; "
        "PRIORITY: priority_factor; PENALTY: penalty_factor; DIRECTED: direction, directed_limitation; "
        "BIDIRECTED: direction, bidirected_limitation) and no others."
    ),
    request=ZoneSetCreateSerializer,
    responses={
        200: ZoneSetSerializer,
        400: bad_request(
            OpenApiExample(
                "Duplicate",
                value={"detail": "Object zone_set with name floor1-v1 already exists"},
                status_codes=["400"],
            ),
            POLYGON_EXAMPLE,
            SCHEMA_ERROR_EXAMPLE,
        ),
    },
    examples=[OpenApiExample("README zone set", value=README_ZONE_SET, request_only=True), ZONE_SET_EXAMPLE],
)

ZONE_SET_GET = dict(
    operation_id="zone_set_get",
    summary="Get a zone set",
    responses={200: ZoneSetSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[ZONE_SET_EXAMPLE],
)

ZONE_SET_ENABLE = dict(
    operation_id="zone_set_enable",
    summary="Enable a zone set on its map",
    description="Makes the zone set its map's enabled one; the set enabled before on that map is disabled.",
    request=None,
    responses={200: ZoneSetSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[ZONE_SET_EXAMPLE],
)

ZONE_SET_DISABLE = dict(
    operation_id="zone_set_disable",
    summary="Disable a zone set",
    description="The zone set's map then has no enabled zone set until one is enabled.",
    request=None,
    responses={200: ZoneSetSerializer, 400: bad_request(NOT_FOUND_EXAMPLE)},
    examples=[
        OpenApiExample(
            "Disabled",
            response_only=True,
            value={**README_ZONE_SET, "status": {"enabled": False}, "lifecycle": "ALIVE"},
        )
    ],
)

ZONE_SET_DELETE = dict(
    operation_id="zone_set_delete",
    summary="Delete a zone set",
    description="Deletes a disabled zone set; a map's enabled zone set is refused.",
    responses={200: DETAIL_RESPONSE, 400: bad_request(NOT_FOUND_TO_CHANGE_EXAMPLE, ENABLED_EXAMPLE)},
    examples=[OpenApiExample("Deleted", value={"detail": "floor1-v0 is DELETED"})],
)

ZONE_GRANT_REVOKE = dict(
    operation_id="zone_grant_revoke",
    summary="Revoke a robot's grant of a zone",
    description=(
        "Takes back the grant of a RELEASE zone of this (enabled) zone set that the robot holds. A robot not "
        "yet in the zone loses it and waits at the zone's edge until it is granted again; one already in it "
        "(or whose released order base crosses it) keeps it until it has left; a VDA 5050 3.0 robot is "
        "answered REVOKED on its responses topic. Applied by the next zone plan run, at once."
    ),
    request=ZoneGrantRevokeSerializer,
    responses={
        200: DETAIL_RESPONSE,
        400: bad_request(
            NOT_FOUND_EXAMPLE,
            OpenApiExample(
                "No such grant",
                value={
                    "message": "Robot carter01 holds no grant of zone aisle1 of zone set floor1-v1.",
                    "error_code": "USAGE",
                },
                status_codes=["400"],
            ),
            SCHEMA_ERROR_EXAMPLE,
        ),
    },
    examples=[
        OpenApiExample("Revoke", value={"robot": "carter01", "zone_id": "aisle1"}, request_only=True),
        OpenApiExample(
            "Revoked", value={"detail": "Grant of zone aisle1 to carter01 is REVOKED"}, response_only=True
        ),
    ],
)
