"""The streams' HTTP side: GET /robot/watch and GET /mission/watch (NDJSON, their viewsets' `watch`
actions) and GET /events (server-sent events, fleet.events), so they authenticate, refuse and validate
filters as every other endpoint. The kinds come from the views (`Source`): the feed knows no robot or
mission."""

import uuid
from collections.abc import Callable
from dataclasses import dataclass, replace

from django.core.handlers.asgi import ASGIRequest
from django.db import connection
from django.db.models import QuerySet
from django.http import HttpResponse, QueryDict, StreamingHttpResponse
from drf_spectacular.utils import extend_schema
from rest_framework import status, viewsets
from rest_framework.decorators import action
from rest_framework.exceptions import APIException, ErrorDetail, ValidationError
from rest_framework.negotiation import DefaultContentNegotiation
from rest_framework.renderers import BaseRenderer
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.serializers import BaseSerializer

from access.selectors import request_credential
from changes.framing import Framing, Ndjson, ServerSentEvents, event_id_span
from changes.selectors import FeedPositionExpired, FeedPositionInvalid
from changes.stream import Opening, Watched, resume, snapshot, watch_stream
from kit.api.errors import QueryValidationError
from kit.api.parsers import InputError

# The reference's, accepted: no client of ours writes status, so there is no echo of its own to hide.
PUBLISHER_ID = "publisher_id"
SNAPSHOT_ONLY_FILTERS = frozenset({"most_recent"})  # how many objects, not which: it shapes the snapshot only
KIND = "kind"  # GET /events: the kinds to watch, repeated; each kind's filters are `<kind>.<filter>`
LAST_EVENT_ID = "last_event_id"  # for clients that cannot send the Last-Event-ID header
LAST_EVENT_ID_HEADER = "HTTP_LAST_EVENT_ID"


@dataclass(frozen=True)
class Source:
    """A kind a stream can show: its list endpoint's selector (which applies and validates the filters)
    and the serializer of its GET."""

    kind: str
    select: Callable[..., QuerySet]
    serializer: type[BaseSerializer]


class StreamsNeedAsgi(APIException):
    """A stream asked of the WSGI application (fleet.wsgi: Django's runserver, say), which would hold one
    of its threads for as long as the stream lasts, and cannot send an async stream anyway."""

    status_code = status.HTTP_501_NOT_IMPLEMENTED
    default_detail = (
        "The streams are served by the ASGI application (fleet.asgi, as deploy/Procfile runs the API); "
        "this server runs the WSGI one."
    )


class AnyAccept(DefaultContentNegotiation):
    """A stream's errors are JSON whatever the client accepts (EventSource accepts only text/event-stream),
    and the stream is what it is."""

    def select_renderer(
        self, request: Request, renderers: list[BaseRenderer], format_suffix: str | None = None
    ) -> tuple[BaseRenderer, str]:
        return renderers[0], renderers[0].media_type


def watch_response(request: Request, source: Source) -> HttpResponse:
    """NDJSON: the objects `source` selects with the request's filters, then each change."""
    if not isinstance(request._request, ASGIRequest):
        raise StreamsNeedAsgi
    filters = request.query_params.copy()
    for value in filters.pop(PUBLISHER_ID, []):
        try:
            uuid.UUID(value)
        except ValueError:
            raise QueryValidationError(
                {PUBLISHER_ID: [ErrorDetail(f"{value!r} is not a UUID.", code="invalid")]}
            ) from None
    watched, queryset = _watched(source, filters)
    return _streaming(request, (watched,), Ndjson(), snapshot([(watched, queryset)]))


def events_response(request: Request, sources: list[Source]) -> HttpResponse:
    """Server-sent events: the objects of the kinds asked for (`kind`, default all) that their filters
    (`<kind>.<filter>`) select, then each change; or, for a client that resumes (Last-Event-ID), every
    change after the last event it had."""
    if not isinstance(request._request, ASGIRequest):
        raise StreamsNeedAsgi
    by_kind = {source.kind: source for source in sources}
    asked = request.query_params.getlist(KIND) or list(by_kind)
    unknown = [kind for kind in asked if kind not in by_kind]
    if unknown:
        message = f"Unknown kind {unknown[0]!r}: one of {', '.join(by_kind)}."
        raise QueryValidationError({KIND: [ErrorDetail(message, code="invalid_choice")]})
    kinds = [kind for kind in by_kind if kind in asked]  # the snapshot in the sources' order
    filters = {kind: QueryDict(mutable=True) for kind in kinds}
    for key, values in request.query_params.lists():
        kind, dot, name = key.partition(".")
        if not dot or kind not in by_kind:
            continue
        if kind not in filters:
            message = (
                f"A filter of {kind}s, but the stream does not show them (kind={kind} is not asked for)."
            )
            raise QueryValidationError({key: [ErrorDetail(message, code="kind_not_watched")]})
        filters[kind].setlist(name, values)
    reads = [_watched(by_kind[kind], filters[kind], prefix=f"{kind}.") for kind in kinds]
    watched = tuple(each for each, _ in reads)
    event_id, loc = _last_event_id(request)
    if not event_id:
        return _streaming(request, watched, ServerSentEvents(), snapshot(reads))
    try:
        opening = resume(watched, event_id_span(event_id))
    except FeedPositionInvalid:
        message = f"{event_id!r} is not an event id this server gave out."
        raise InputError(message, type="invalid_event_id", loc=loc) from None
    except FeedPositionExpired as error:
        detail = f"Cannot resume after this event ({error}): a new snapshot follows."
        opening = replace(snapshot(reads), notice=("resume_expired", detail))
    return _streaming(request, watched, ServerSentEvents(), opening)


def _watched(source: Source, filters: QueryDict, *, prefix: str = "") -> tuple[Watched, QuerySet]:
    """What a stream watches of `source`'s kind with these filters, and the queryset of its snapshot; the
    list endpoint's 400 for bad filters (their names after `prefix`)."""
    per_object = filters.copy()
    for name in SNAPSHOT_ONLY_FILTERS:
        per_object.pop(name, None)
    watched = Watched(
        kind=source.kind,
        query=lambda: source.select(filters=per_object),
        filters=tuple(sorted((key, tuple(per_object.getlist(key))) for key in per_object)),
        serializer=source.serializer,
    )
    try:
        return watched, source.select(filters=filters)
    except ValidationError as error:
        raise QueryValidationError({prefix + key: value for key, value in error.detail.items()}) from None


def _last_event_id(request: Request) -> tuple[str, tuple[str, str]]:
    """The id of the last event the client had, and where it came from: the Last-Event-ID header
    (EventSource sends it when it reconnects), else the last_event_id parameter; empty for a new stream."""
    header = request.META.get(LAST_EVENT_ID_HEADER, "")
    if header:
        return header, ("header", "Last-Event-ID")
    return request.query_params.get(LAST_EVENT_ID, ""), ("query", LAST_EVENT_ID)


def _streaming(
    request: Request, watched: tuple[Watched, ...], framing: Framing, opening: Opening
) -> StreamingHttpResponse:
    # The stream may stay open for hours, its changes read on the poller's connection: this request's
    # connection is let go now, not at the stream's end.
    credential = request_credential(request)
    connection.close()
    response = StreamingHttpResponse(
        watch_stream(watched, framing, opening, credential), content_type=framing.content_type
    )
    response["Cache-Control"] = "no-cache"
    response["X-Accel-Buffering"] = "no"  # a reverse proxy passes each event on at once
    return response


class WatchedViewSet(viewsets.GenericViewSet):
    """The endpoints of a kind of named object whose list (GET /<kind>) and watch stream (GET
    /<kind>/watch) show the same `source`: the list's filters select what the stream shows, and both show
    objects as GET /<kind>/{name} does. `queryset` and `filterset_class` describe the endpoints for the
    OpenAPI schema; reads go through the source's selector, which applies the same filters."""

    source: Source
    lookup_field = "name"
    lookup_value_regex = "[^/]+"

    def list(self, request: Request) -> Response:
        objects = self.source.select(filters=request.query_params)
        return Response(self.source.serializer(objects, many=True).data)

    # The reference hides its watch streams from OpenAPI; so do we. A list route: it comes before
    # /<kind>/{name}, so "watch" is never taken for an object's name.
    @extend_schema(exclude=True)
    @action(detail=False, methods=["get"], url_path="watch", content_negotiation_class=AnyAccept)
    def watch(self, request: Request) -> HttpResponse:
        """NDJSON: every object the filters select, then each change (README "Watch streams")."""
        return watch_response(request, self.source)
