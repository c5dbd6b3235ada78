"""The stream process's poller (changes.stream.Hub) when its poll fails for a reason other than the
database: its watchers' streams end with an error instead of staying open and silent, in either framing
(an SSE client keeps its resume id: nothing was lost)."""

import asyncio

import orjson

from changes.framing import Framing, Ndjson, ServerSentEvents
from changes.stream import Hub, Watched, Watcher
from robots.api.serializers import RobotSerializer


def _query_that_fails() -> None:
    raise ValueError("a poll that fails whatever the database does")


async def _stream_of_a_watcher_whose_poll_fails(framing: Framing) -> list[bytes | None]:
    hub = Hub()
    watched = Watched(kind="robot", query=_query_that_fails, filters=(), serializer=RobotSerializer)
    watcher = Watcher(watched=(watched,), framing=framing, since="1:1:")
    hub.add(watcher)
    return await asyncio.wait_for(watcher.take(), timeout=10)


def test_a_poll_that_fails_ends_the_streams_with_an_error_line() -> None:
    error, end = asyncio.run(_stream_of_a_watcher_whose_poll_fails(Ndjson()))

    assert orjson.loads(error)["error"] == "feed_failed"
    assert end is None


def test_a_poll_that_fails_ends_the_event_streams_with_an_error_event() -> None:
    error, end = asyncio.run(_stream_of_a_watcher_whose_poll_fails(ServerSentEvents()))

    event, data, blank = error.split(b"\n", 2)
    assert event == b"event: error"
    assert orjson.loads(data.removeprefix(b"data: "))["error"] == "feed_failed"
    assert blank == b"\n"  # no id line: the client resumes from its last event
    assert end is None
