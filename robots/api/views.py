"""Robot endpoints: thin methods that validate input, call a selector or service, and serialize."""

from drf_spectacular.utils import extend_schema, extend_schema_view
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response

from access.authentication import request_actor
from changes.choices import ChangeKind
from changes.views import Source, WatchedViewSet
from kit.api.serializers import body_validated, query_validated
from robots.api import schema
from robots.api.serializers import (
    MapActionRequestSerializer,
    MapActionSerializer,
    RobotCreateSerializer,
    RobotMapsSerializer,
    RobotSerializer,
    RobotSpecSerializer,
    TeleopQuerySerializer,
)
from robots.choices import TeleopAction
from robots.filters import RobotFilter
from robots.models import Robot
from robots.selectors import robot_get, robot_list, robot_map_actions
from robots.services import (
    robot_charge,
    robot_create,
    robot_delete,
    robot_map_action,
    robot_teleop,
    robot_update_spec,
)

# What the streams show of robots (GET /robot/watch, GET /events): GET /robot's filters, GET
# /robot/{name}'s JSON.
ROBOTS = Source(kind=ChangeKind.ROBOT, select=robot_list, serializer=RobotSerializer)


@extend_schema_view(
    list=extend_schema(**schema.ROBOT_LIST),
    create=extend_schema(**schema.ROBOT_CREATE),
    retrieve=extend_schema(**schema.ROBOT_GET),
    update=extend_schema(**schema.ROBOT_UPDATE),
    destroy=extend_schema(**schema.ROBOT_DELETE),
)
class RobotViewSet(WatchedViewSet):
    """Robots. `queryset` and `filterset_class` describe the endpoints for the OpenAPI schema; reads go
    through the selectors, which apply the same RobotFilter."""

    source = ROBOTS
    queryset = Robot.objects.all()
    serializer_class = RobotSerializer
    filterset_class = RobotFilter

    def create(self, request: Request) -> Response:
        spec = body_validated(RobotCreateSerializer, request.data)
        robot = robot_create(
            actor=request_actor(request), name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec
        )
        return Response(RobotSerializer(robot).data)

    def retrieve(self, request: Request, name: str) -> Response:
        return Response(RobotSerializer(robot_get(name=name)).data)

    def update(self, request: Request, name: str) -> Response:
        spec = body_validated(RobotSpecSerializer, request.data)
        robot = robot_update_spec(
            actor=request_actor(request), robot=robot_get(name=name, to_change=True), spec=spec
        )
        return Response(RobotSerializer(robot).data)

    def destroy(self, request: Request, name: str) -> Response:
        robot_delete(actor=request_actor(request), robot=robot_get(name=name, to_change=True))
        return Response({"detail": f"{name} is PENDING_DELETE"})

    @extend_schema(**schema.ROBOT_TELEOP)
    @action(detail=True, methods=["post"])
    def teleop(self, request: Request, name: str) -> Response:
        query = query_validated(TeleopQuerySerializer, request.query_params)
        teleop_action = TeleopAction(query["params"])
        robot_teleop(actor=request_actor(request), robot=robot_get(name=name), action=teleop_action)
        return Response(f"{teleop_action} teleop action received.")

    @extend_schema(**schema.ROBOT_CHARGE)
    @action(detail=True, methods=["post"])
    def charge(self, request: Request, name: str) -> Response:
        robot = robot_charge(actor=request_actor(request), robot=robot_get(name=name))
        return Response(RobotSerializer(robot).data)

    @extend_schema(**schema.ROBOT_MAPS)
    @extend_schema(**schema.ROBOT_MAP_ACTION)
    @action(detail=True, methods=["get", "post"], url_path="map")
    def map(self, request: Request, name: str) -> Response:
        robot = robot_get(name=name)
        if request.method == "GET":
            return Response(
                RobotMapsSerializer({"maps": robot.maps, "actions": robot_map_actions(robot=robot)}).data
            )
        body = body_validated(MapActionRequestSerializer, request.data)
        queued = robot_map_action(actor=request_actor(request), robot=robot, **body)
        return Response(MapActionSerializer(queued).data)
