"""The stream process's poller (changes.stream.Hub) when its poll fails for a reason other than the
database: its watchers' streams end with an error line instead of staying open and silent."""

import asyncio

import orjson

from changes.stream import Hub, Watched, Watcher
from robots.api.serializers import RobotSerializer


def _query_that_fails() -> None:
    raise ValueError("a poll that fails whatever the database does")


async def _stream_of_a_watcher_whose_poll_fails() -> list[bytes | None]:
    hub = Hub()
    watched = Watched(kind="robot", query=_query_that_fails, filters=(), serializer=RobotSerializer)
    watcher = Watcher(watched=watched, since="1:1:")
    hub.add(watcher)
    lines = [await asyncio.wait_for(watcher.queue.get(), timeout=10)]
    lines.append(await asyncio.wait_for(watcher.queue.get(), timeout=10))
    return lines


def test_a_poll_that_fails_ends_the_streams_with_an_error_line() -> None:
    error, end = asyncio.run(_stream_of_a_watcher_whose_poll_fails())

    assert orjson.loads(error)["error"] == "feed_failed"
    assert end is None
