"""Station endpoints: thin methods that validate input, call a selector or service, and serialize."""

from drf_spectacular.utils import extend_schema, extend_schema_view
from rest_framework.request import Request
from rest_framework.response import Response

from access.authentication import request_actor
from changes.choices import ChangeKind
from changes.views import Source, WatchedViewSet
from kit.api.serializers import body_validated
from stations.api import schema
from stations.api.serializers import StationCreateSerializer, StationSerializer, StationSpecSerializer
from stations.filters import StationFilter
from stations.models import Station
from stations.selectors import station_get, station_list
from stations.services import station_create, station_delete, station_update_spec

# What the streams show of stations (GET /station/watch, GET /events): GET /station's filters, GET
# /station/{name}'s JSON.
STATIONS = Source(kind=ChangeKind.STATION, select=station_list, serializer=StationSerializer)


@extend_schema_view(
    list=extend_schema(**schema.STATION_LIST),
    create=extend_schema(**schema.STATION_CREATE),
    retrieve=extend_schema(**schema.STATION_GET),
    update=extend_schema(**schema.STATION_UPDATE),
    destroy=extend_schema(**schema.STATION_DELETE),
)
class StationViewSet(WatchedViewSet):
    """Stations; reads go through the selectors, which apply StationFilter."""

    source = STATIONS
    queryset = Station.objects.all()
    serializer_class = StationSerializer
    filterset_class = StationFilter

    def create(self, request: Request) -> Response:
        spec = body_validated(StationCreateSerializer, request.data)
        station = station_create(
            actor=request_actor(request), name=spec.pop("name"), prefix=spec.pop("prefix"), spec=spec
        )
        return Response(StationSerializer(station).data)

    def retrieve(self, request: Request, name: str) -> Response:
        return Response(StationSerializer(station_get(name=name)).data)

    def update(self, request: Request, name: str) -> Response:
        spec = body_validated(StationSpecSerializer, request.data)
        station = station_update_spec(
            actor=request_actor(request), station=station_get(name=name, to_change=True), spec=spec
        )
        return Response(StationSerializer(station).data)

    def destroy(self, request: Request, name: str) -> Response:
        station_delete(actor=request_actor(request), station=station_get(name=name, to_change=True))
        return Response({"detail": f"{name} is DELETED"})
