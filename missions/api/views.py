"""Mission endpoints and GET /behaviors: thin methods that validate input, call a selector or service, and
serialize."""

from drf_spectacular.utils import extend_schema, extend_schema_view
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from access.authentication import request_actor
from changes.choices import ChangeKind
from changes.views import Source, WatchedViewSet
from kit.api.serializers import body_validated
from missions.api import schema
from missions.api.serializers import (
    NODE_KIND_SERIALIZERS,
    MissionCreateSerializer,
    MissionSerializer,
    RouteUpdatesField,
    node_description,
)
from missions.filters import MissionFilter
from missions.models import Mission
from missions.selectors import mission_get, mission_list
from missions.services import mission_cancel, mission_create, mission_delete, mission_update_routes

# What the streams show of missions (GET /mission/watch, GET /events): GET /mission's filters, GET
# /mission/{name}'s JSON.
MISSIONS = Source(kind=ChangeKind.MISSION, select=mission_list, serializer=MissionSerializer)


@extend_schema_view(
    list=extend_schema(**schema.MISSION_LIST),
    create=extend_schema(**schema.MISSION_CREATE),
    retrieve=extend_schema(**schema.MISSION_GET),
    destroy=extend_schema(**schema.MISSION_DELETE),
)
class MissionViewSet(WatchedViewSet):
    """Missions. `queryset` and `filterset_class` describe the endpoints for the OpenAPI schema; reads go
    through the selectors, which apply the same MissionFilter."""

    source = MISSIONS
    queryset = Mission.objects.all()
    serializer_class = MissionSerializer
    filterset_class = MissionFilter

    def create(self, request: Request) -> Response:
        spec = body_validated(MissionCreateSerializer, request.data)
        mission = mission_create(
            actor=request_actor(request), name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec
        )
        return Response(MissionSerializer(mission).data)

    def retrieve(self, request: Request, name: str) -> Response:
        return Response(MissionSerializer(mission_get(name=name)).data)

    def destroy(self, request: Request, name: str) -> Response:
        mission_delete(actor=request_actor(request), mission=mission_get(name=name, to_change=True))
        return Response({"detail": f"{name} is PENDING_DELETE"})

    @extend_schema(**schema.MISSION_CANCEL)
    @action(detail=True, methods=["post"])
    def cancel(self, request: Request, name: str) -> Response:
        mission_cancel(actor=request_actor(request), mission=mission_get(name=name))
        return Response({"detail": f"Mission {name} will be canceled."})

    @extend_schema(**schema.MISSION_UPDATE)
    @action(detail=True, methods=["post"], url_path="update")
    def update_routes(self, request: Request, name: str) -> Response:
        update_nodes = RouteUpdatesField().run_validation(request.data)
        mission_update_routes(
            actor=request_actor(request), mission=mission_get(name=name), update_nodes=update_nodes
        )
        return Response(RouteUpdatesField().to_representation(update_nodes))


class BehaviorsView(APIView):
    """The mission tree node kinds and their parameters."""

    @extend_schema(**schema.BEHAVIORS)
    def get(self, request: Request) -> Response:
        return Response(
            [
                {"name": kind, "params": list(serializer().fields), "description": node_description(kind)}
                for kind, serializer in NODE_KIND_SERIALIZERS.items()
            ]
        )
