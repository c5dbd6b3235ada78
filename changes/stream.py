"""Watch streams (GET /robot/watch, GET /mission/watch): a snapshot, then every committed change, as
NDJSON, from the change feed (changes.models.Change).

Served from the ASGI process (`stream` in deploy/Procfile): a watcher is a queue in the event loop, not a
thread. One poller per process reads the feed for all its watchers: watchers with the same filters at the
same feed position share one query and one serialization per poll.

A watcher goes from feed position to feed position (changes.selectors reads the feed), so it has every
committed change once.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import orjson
from django.conf import settings
from django.db import DatabaseError, connection
from django.db.models import Model, QuerySet
from rest_framework.serializers import BaseSerializer

from changes.selectors import watch_changes, watch_snapshot

logger = logging.getLogger(__name__)

QueryFor = Callable[[], QuerySet]  # the watcher's filtered queryset, built anew for each read


@dataclass(frozen=True)
class Watched:
    """What a watch stream shows: objects of `kind`, the rows `query` selects, as `serializer` has them."""

    kind: str
    query: QueryFor  # the list endpoint's filters that select single objects (not a count: most_recent)
    filters: tuple[tuple[str, tuple[str, ...]], ...]  # the request's: watchers that share them share reads
    serializer: type[BaseSerializer]


@dataclass(eq=False)
class Watcher:
    watched: Watched
    since: str  # the feed position this watcher has had every change up to
    queue: asyncio.Queue[bytes | None] = field(default_factory=asyncio.Queue)
    sent: dict[str, int] = field(default_factory=dict)  # each object's last line, hashed: no line twice
    dropped: bool = False

    def offer(self, name: str, line: bytes) -> None:
        """Queue `line` unless it repeats the object's last one; a watcher too far behind is told, dropped."""
        digest = hash(line)
        if self.sent.get(name) == digest or self.dropped:
            return
        self.sent[name] = digest
        if self.queue.qsize() >= settings.WATCH_QUEUE_LINES:
            self.drop(
                "watcher_behind",
                f"More than {settings.WATCH_QUEUE_LINES} {self.watched.kind} changes waited for this "
                "watcher: it is dropped. Watch again for a new snapshot.",
            )
            return
        self.queue.put_nowait(line)

    def drop(self, error: str, detail: str) -> None:
        """End the stream with an error line in place of whatever still waits: the client watches again."""
        self.dropped = True
        while not self.queue.empty():
            self.queue.get_nowait()
        self.queue.put_nowait(orjson.dumps({"error": error, "detail": detail}) + b"\n")
        self.queue.put_nowait(None)


def snapshot(watched: Watched, queryset: QuerySet) -> tuple[str, list[tuple[str, bytes]]]:
    """The snapshot's lines and the feed position they are at. Synchronous: the view calls it."""
    position, rows = watch_snapshot(queryset=queryset)
    return position, [(row.pk, _line(watched.serializer, row)) for row in rows]


def _line(serializer: type[BaseSerializer], instance: Model) -> bytes:
    return orjson.dumps(serializer(instance).data) + b"\n"


def _read(groups: list[tuple[Watched, str]]) -> tuple[str, list[list[tuple[str, bytes]]]]:
    """One poll: the feed position now and, for each (watched, since), its changes' lines up to there."""
    position, changes = watch_changes(
        reads=[(watched.kind, watched.query(), since) for watched, since in groups]
    )
    lines = [
        [(row.pk, _line(watched.serializer, row)) for row in rows]
        for (watched, _), rows in zip(groups, changes, strict=True)
    ]
    return position, lines


class Hub:
    """The process's watchers and the one task that polls the feed for them."""

    def __init__(self) -> None:
        self.watchers: set[Watcher] = set()
        self._task: asyncio.Task[None] | None = None
        # One thread, one database connection: the poller's reads never wait for a request's thread.
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="watch-poller")

    def add(self, watcher: Watcher) -> None:
        self.watchers.add(watcher)
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._poll_forever())

    def remove(self, watcher: Watcher) -> None:
        self.watchers.discard(watcher)

    async def _poll_forever(self) -> None:
        loop = asyncio.get_running_loop()
        while self.watchers:
            await asyncio.sleep(settings.WATCH_POLL_SECONDS)
            watchers = [watcher for watcher in self.watchers if not watcher.dropped]
            groups: dict[tuple[str, tuple, str], list[Watcher]] = {}
            for watcher in watchers:
                key = (watcher.watched.kind, watcher.watched.filters, watcher.since)
                groups.setdefault(key, []).append(watcher)
            keys = list(groups)
            try:
                position, changes = await loop.run_in_executor(
                    self._executor, _read, [(groups[key][0].watched, key[2]) for key in keys]
                )
            except DatabaseError:
                # PostgreSQL away: the positions stand, the next poll reads from them again.
                logger.warning("The change feed could not be read; retrying", exc_info=True)
                await loop.run_in_executor(self._executor, connection.close)
                continue
            except Exception:
                # Anything else would fail again at every poll: end the streams rather than leave them
                # silent; a watcher that watches again starts a new poller.
                logger.exception("The change feed's poll failed; ending this process's watch streams")
                for watcher in list(self.watchers):
                    watcher.drop("feed_failed", "The server could not read the change feed. Watch again.")
                self.watchers.clear()
                return
            for key, lines in zip(keys, changes, strict=True):
                for watcher in groups[key]:
                    for name, line in lines:
                        watcher.offer(name, line)
                    watcher.since = position


HUB = Hub()


async def watch_lines(
    watched: Watched, position: str, lines: list[tuple[str, bytes]]
) -> AsyncIterator[bytes]:
    """The snapshot's lines, then each change's, until the client goes or falls too far behind."""
    watcher = Watcher(watched=watched, since=position)
    watcher.sent.update((name, hash(line)) for name, line in lines)
    HUB.add(watcher)
    try:
        yield b""  # the response's headers go out now, not with the first line, which may be a long while
        for _, line in lines:
            yield line
        while (line := await watcher.queue.get()) is not None:
            yield line
    finally:
        HUB.remove(watcher)
