"""GET /events: robots', missions', stations' and zone sets' changes as server-sent events (README
"Watching the fleet"). It shows several apps' objects, so it lives beside the URLconf; the stream itself is
changes.views'."""

from django.http import HttpResponse
from drf_spectacular.utils import extend_schema
from rest_framework.request import Request
from rest_framework.views import APIView

from changes.views import AnyAccept, events_response
from missions.api.views import MISSIONS
from robots.api.views import ROBOTS
from stations.api.views import STATIONS
from zones.api.views import ZONE_SETS


class EventsView(APIView):
    content_negotiation_class = AnyAccept

    # Endless, as the watch streams, which OpenAPI does not show either (a schema-driven client would
    # wait on it forever).
    @extend_schema(exclude=True)
    def get(self, request: Request) -> HttpResponse:
        return events_response(request, [ROBOTS, MISSIONS, STATIONS, ZONE_SETS])
