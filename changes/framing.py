"""How a stream frames the feed's objects: NDJSON for the watch streams (GET /robot/watch, GET /mission/watch,
the reference's), server-sent events for GET /events. One feed, one watcher, two framings.

An SSE event's id is where a client that saw it resumes (changes.selectors.Span): a position alone
(`<snapshot>`: every change up to it delivered), or a change in the middle of a read
(`<since>/<until>/<change id>`: every change up to `since`, and those of the read up to `until` up to
that change). The objects of a snapshot have no position of their own, so they carry an empty id: a client
cut off in the middle of a snapshot comes back without one and gets a new snapshot.
"""

import re
from typing import Protocol

import orjson
from django.conf import settings

from changes.selectors import FeedPositionInvalid, Span

NDJSON_TYPE = "application/x-ndjson"
SSE_TYPE = "text/event-stream"
ID_SEPARATOR = "/"  # not in a pg_snapshot's text (digits, ':' and ',')


class Item(Protocol):
    change: int
    kind: str
    data: bytes


class Framing(Protocol):
    content_type: str
    keepalive_seconds: float | None  # None: no keepalive

    def start(self) -> bytes: ...

    def item(self, item: Item, *, since: str | None, position: str) -> bytes: ...

    def snapshot_end(self, position: str) -> bytes: ...

    def error(self, error: str, detail: str, *, resumable: bool = True) -> bytes: ...

    def keepalive(self, position: str) -> bytes: ...


class Ndjson:
    """One line per object, as GET shows it; an error is a line `{"error", "detail"}`."""

    content_type = NDJSON_TYPE
    keepalive_seconds = None

    def start(self) -> bytes:
        return b""

    def item(self, item: Item, *, since: str | None, position: str) -> bytes:
        return item.data + b"\n"

    def snapshot_end(self, position: str) -> bytes:
        return b""

    def error(self, error: str, detail: str, *, resumable: bool = True) -> bytes:
        return orjson.dumps({"error": error, "detail": detail}) + b"\n"

    def keepalive(self, position: str) -> bytes:
        return b""


class ServerSentEvents:
    """`event: <kind>`, `data:` the object as GET shows it, `id:` where to resume; `snapshot_end` after a
    snapshot; `error` events; a keepalive comment that also moves the client's resume id along (a block
    with an id and no data dispatches no event), so a quiet stream does not age out of the retention
    window."""

    content_type = SSE_TYPE

    @property
    def keepalive_seconds(self) -> float:
        return settings.EVENTS_KEEPALIVE_SECONDS

    def start(self) -> bytes:
        return f"retry: {round(settings.EVENTS_RETRY_SECONDS * 1000)}\n\n".encode()

    def item(self, item: Item, *, since: str | None, position: str) -> bytes:
        event_id = "" if since is None else ID_SEPARATOR.join((since, position, str(item.change)))
        return f"id: {event_id}\nevent: {item.kind}\ndata: ".encode() + item.data + b"\n\n"

    def snapshot_end(self, position: str) -> bytes:
        return f"id: {position}\nevent: snapshot_end\ndata: {{}}\n\n".encode()

    def error(self, error: str, detail: str, *, resumable: bool = True) -> bytes:
        # Not resumable: the id is cleared, so the client's reconnection asks for a new snapshot.
        reset = b"" if resumable else b"id: \n"
        return reset + b"event: error\ndata: " + orjson.dumps({"error": error, "detail": detail}) + b"\n\n"

    def keepalive(self, position: str) -> bytes:
        return f": keepalive\nid: {position}\n\n".encode()


def event_id_span(event_id: str) -> Span:
    """The span an SSE client resumes from; FeedPositionInvalid for an id no stream gave out."""
    parts = event_id.split(ID_SEPARATOR)
    if len(parts) == 1:
        return Span(since=parts[0])
    if len(parts) == 3 and re.fullmatch("[0-9]{1,18}", parts[2]):
        return Span(since=parts[0], until=parts[1], after=int(parts[2]))
    raise FeedPositionInvalid(event_id)
