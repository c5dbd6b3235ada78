"""The watch streams' HTTP side, shared by GET /robot/watch and GET /mission/watch (their viewsets' `watch`
actions, so they authenticate, refuse and validate filters as every other endpoint)."""

import uuid
from collections.abc import Callable

from django.conf import settings
from django.core.handlers.asgi import ASGIRequest
from django.db import connection
from django.db.models import QuerySet
from django.http import HttpResponse, HttpResponseRedirect, StreamingHttpResponse
from rest_framework.exceptions import ErrorDetail
from rest_framework.request import Request
from rest_framework.serializers import BaseSerializer

from changes.stream import Watched, snapshot, watch_lines
from fleet.api import QueryValidationError

NDJSON = "application/x-ndjson"
# The reference's, accepted: no client of ours writes status, so there is no echo of its own to hide.
PUBLISHER_ID = "publisher_id"
SNAPSHOT_ONLY_FILTERS = frozenset({"most_recent"})  # how many objects, not which: it shapes the snapshot only


class WatchRedirect(HttpResponseRedirect):
    status_code = 307  # the same GET, to the stream process


def watch_response(
    request: Request,
    *,
    kind: str,
    select: Callable[..., QuerySet],
    serializer: type[BaseSerializer],
) -> HttpResponse:
    """A stream of the objects `select` (the list endpoint's selector) picks with the request's filters: the
    snapshot, then each change. The WSGI API keeps its threads for requests: it sends the client to the
    stream process."""
    if not isinstance(request._request, ASGIRequest):
        return WatchRedirect(_stream_url(request))
    filters = request.query_params.copy()
    publisher = filters.pop(PUBLISHER_ID, [])
    for value in publisher:
        try:
            uuid.UUID(value)
        except ValueError:
            raise QueryValidationError(
                {PUBLISHER_ID: [ErrorDetail(f"{value!r} is not a UUID.", code="invalid")]}
            ) from None
    per_object = filters.copy()
    for name in SNAPSHOT_ONLY_FILTERS:
        per_object.pop(name, None)
    watched = Watched(
        kind=kind,
        query=lambda: select(filters=per_object),
        filters=tuple(sorted((key, tuple(per_object.getlist(key))) for key in per_object)),
        serializer=serializer,
    )
    position, lines = snapshot(watched, select(filters=filters))
    # The stream may stay open for hours, its changes read on the poller's connection: this request's
    # connection is let go now, not at the stream's end.
    connection.close()
    response = StreamingHttpResponse(watch_lines(watched, position, lines), content_type=NDJSON)
    response["Cache-Control"] = "no-cache"
    response["X-Accel-Buffering"] = "no"  # a reverse proxy passes each line on at once
    return response


def _stream_url(request: Request) -> str:
    host = request.get_host().rsplit(":", 1)[0]
    base = settings.STREAM_URL or f"{request.scheme}://{host}:{settings.STREAM_PORT}"
    return base.rstrip("/") + request.get_full_path()
