"""Zone set endpoints: thin methods that validate input, call a selector or service, and serialize."""

from drf_spectacular.utils import extend_schema, extend_schema_view
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response

from access.authentication import request_actor
from changes.choices import ChangeKind
from changes.views import Source, WatchedViewSet
from kit.api.serializers import body_validated
from zones.api import schema
from zones.api.serializers import ZoneGrantRevokeSerializer, ZoneSetCreateSerializer, ZoneSetSerializer
from zones.filters import ZoneSetFilter
from zones.models import ZoneSet
from zones.selectors import zone_set_get, zone_set_list
from zones.services import (
    zone_grant_revoke,
    zone_set_create,
    zone_set_delete,
    zone_set_disable,
    zone_set_enable,
)

# What the streams show of zone sets (GET /zone_set/watch, GET /events): GET /zone_set's filters, GET
# /zone_set/{name}'s JSON.
ZONE_SETS = Source(kind=ChangeKind.ZONE_SET, select=zone_set_list, serializer=ZoneSetSerializer)


@extend_schema_view(
    list=extend_schema(**schema.ZONE_SET_LIST),
    create=extend_schema(**schema.ZONE_SET_CREATE),
    retrieve=extend_schema(**schema.ZONE_SET_GET),
    destroy=extend_schema(**schema.ZONE_SET_DELETE),
)
class ZoneSetViewSet(WatchedViewSet):
    """Zone sets (no update: a zone set's content is immutable); reads go through the selectors, which
    apply ZoneSetFilter."""

    source = ZONE_SETS
    queryset = ZoneSet.objects.all()
    serializer_class = ZoneSetSerializer
    filterset_class = ZoneSetFilter

    def create(self, request: Request) -> Response:
        spec = body_validated(ZoneSetCreateSerializer, request.data)
        zone_set = zone_set_create(
            actor=request_actor(request), name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec
        )
        return Response(ZoneSetSerializer(zone_set).data)

    def retrieve(self, request: Request, name: str) -> Response:
        return Response(ZoneSetSerializer(zone_set_get(name=name)).data)

    def destroy(self, request: Request, name: str) -> Response:
        zone_set_delete(actor=request_actor(request), zone_set=zone_set_get(name=name, to_change=True))
        return Response({"detail": f"{name} is DELETED"})

    @extend_schema(**schema.ZONE_SET_ENABLE)
    @action(detail=True, methods=["post"])
    def enable(self, request: Request, name: str) -> Response:
        zone_set = zone_set_enable(actor=request_actor(request), zone_set=zone_set_get(name=name))
        return Response(ZoneSetSerializer(zone_set).data)

    @extend_schema(**schema.ZONE_SET_DISABLE)
    @action(detail=True, methods=["post"])
    def disable(self, request: Request, name: str) -> Response:
        zone_set = zone_set_disable(actor=request_actor(request), zone_set=zone_set_get(name=name))
        return Response(ZoneSetSerializer(zone_set).data)

    @extend_schema(**schema.ZONE_GRANT_REVOKE)
    @action(detail=True, methods=["post"])
    def revoke(self, request: Request, name: str) -> Response:
        body = body_validated(ZoneGrantRevokeSerializer, request.data)
        zone_grant_revoke(
            actor=request_actor(request),
            zone_set=zone_set_get(name=name),
            robot=body["robot"],
            zone_id=body["zone_id"],
        )
        return Response({"detail": f"Grant of zone {body['zone_id']} to {body['robot']} is REVOKED"})
