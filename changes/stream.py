"""Watch streams (GET /robot/watch, GET /mission/watch as NDJSON; GET /events as server-sent events): a
snapshot (or, for a resuming SSE client, what it has not had), then every committed change, from the
change feed (changes.models.Change).

Served from an ASGI process (fleet.asgi): a watcher is a queue in the event loop, not a thread. One poller
per process reads the feed for all its watchers: watchers of one kind with the same filters at the same
feed position share one query and one serialization per poll, whatever their framing.

A watcher goes from feed position to feed position (changes.selectors reads the feed), so it has every
committed change once; a watcher of several kinds gets one read's changes of all of them in feed order.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
from collections.abc import AsyncIterator, Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from operator import attrgetter

import orjson
from django.conf import settings
from django.db import DatabaseError, connection
from django.db.models import Model, QuerySet
from rest_framework.serializers import BaseSerializer

from changes.framing import Framing
from changes.selectors import Span, watch_changes, watch_resume, watch_snapshot

logger = logging.getLogger(__name__)

QueryFor = Callable[[], QuerySet]  # the watcher's filtered queryset, built anew for each read


@dataclass(frozen=True)
class Watched:
    """What a stream shows of one kind: objects of `kind`, the rows `query` selects, as `serializer` has
    them."""

    kind: str
    query: QueryFor  # the list endpoint's filters that select single objects (not a count: most_recent)
    filters: tuple[tuple[str, tuple[str, ...]], ...]  # the request's: watchers that share them share reads
    serializer: type[BaseSerializer]


@dataclass(frozen=True)
class Item:
    """One object as one change (or the snapshot) left it."""

    change: int  # the change's id in the feed: the order within a read (0 in a snapshot)
    kind: str
    name: str
    data: bytes  # its JSON, as GET shows it


@dataclass(eq=False)
class Watcher:
    watched: tuple[Watched, ...]
    framing: Framing
    since: str  # the feed position this watcher has had every change up to
    queue: asyncio.Queue[bytes | None] = field(default_factory=asyncio.Queue)
    sent: dict[tuple[str, str], int] = field(default_factory=dict)  # each object's last data, hashed
    dropped: bool = False

    def deliver(self, items: Iterable[Item], position: str) -> None:
        """Queue one read's items (the changes after `since` up to `position`); the watcher is then at
        `position`."""
        for item in items:
            self.offer(item, position)
        self.since = position

    def offer(self, item: Item, position: str) -> None:
        """Queue `item` unless it repeats the object's last one; a watcher too far behind is told, dropped."""
        key, digest = (item.kind, item.name), hash(item.data)
        if self.sent.get(key) == digest or self.dropped:
            return
        self.sent[key] = digest
        if self.queue.qsize() >= settings.WATCH_QUEUE_LINES:
            self.drop(
                "watcher_behind",
                f"More than {settings.WATCH_QUEUE_LINES} changes waited for this watcher: it is dropped. "
                "Watch again for a new snapshot.",
                resumable=False,
            )
            return
        self.queue.put_nowait(self.framing.item(item, since=self.since, position=position))

    def drop(self, error: str, detail: str, *, resumable: bool) -> None:
        """End the stream with an error in place of whatever still waits: the client watches again (SSE:
        resuming where it was if `resumable`, else with a new snapshot)."""
        self.dropped = True
        while not self.queue.empty():
            self.queue.get_nowait()
        self.queue.put_nowait(self.framing.error(error, detail, resumable=resumable))
        self.queue.put_nowait(None)


@dataclass(frozen=True)
class Opening:
    """What a stream sends before the changes the poller brings: a snapshot's items (`since` None), or
    those of a resume, read after `since`; the watcher goes on from `position`."""

    position: str
    items: list[Item]
    since: str | None = None
    notice: tuple[str, str] | None = None  # an error the client is told first, (error, detail)


def snapshot(reads: list[tuple[Watched, QuerySet]]) -> Opening:
    """The snapshot: each kind's objects, kind after kind. Synchronous: the view calls it."""
    position, rows = watch_snapshot(querysets=[queryset for _, queryset in reads])
    items = [
        _item(watched, row) for (watched, _), kind_rows in zip(reads, rows, strict=True) for row in kind_rows
    ]
    return Opening(position=position, items=items)


def resume(watched: tuple[Watched, ...], span: Span) -> Opening:
    """What a stream that stopped at `span` has not had, in feed order (changes.selectors.watch_resume,
    whose errors it raises). Synchronous: the view calls it."""
    position, rows = watch_resume(
        reads=[(each.kind, each.query()) for each in watched], span=span, limit=settings.WATCH_QUEUE_LINES
    )
    kinds = [[_item(each, row) for row in kind_rows] for each, kind_rows in zip(watched, rows, strict=True)]
    return Opening(position=position, items=list(_in_feed_order(kinds)), since=span.since)


def _item(watched: Watched, row: Model) -> Item:
    data = orjson.dumps(watched.serializer(row).data)
    return Item(change=getattr(row, "change_id", 0), kind=watched.kind, name=row.pk, data=data)


def _in_feed_order(kinds: list[list[Item]]) -> Iterable[Item]:
    """One read's items of several kinds as one sequence, by change id (each kind's already is)."""
    return kinds[0] if len(kinds) == 1 else heapq.merge(*kinds, key=attrgetter("change"))


ReadKey = tuple[str, tuple, str]  # (kind, filters, since): the watchers that share a read


def _read_key(watched: Watched, since: str) -> ReadKey:
    return watched.kind, watched.filters, since


def _read(reads: list[tuple[Watched, str]]) -> tuple[str, list[list[Item]]]:
    """One poll: the feed position now and, for each (watched, since), its changes' items up to there."""
    position, changes = watch_changes(
        reads=[(watched.kind, watched.query(), since) for watched, since in reads]
    )
    items = [[_item(watched, row) for row in rows] for (watched, _), rows in zip(reads, changes, strict=True)]
    return position, items


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
            reads: dict[ReadKey, Watched] = {}
            for watcher in watchers:
                for watched in watcher.watched:
                    reads.setdefault(_read_key(watched, watcher.since), watched)
            keys = list(reads)
            try:
                position, changes = await loop.run_in_executor(
                    self._executor, _read, [(reads[key], key[2]) for key in keys]
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
                    watcher.drop(
                        "feed_failed",
                        "The server could not read the change feed. Watch again.",
                        resumable=True,
                    )
                self.watchers.clear()
                return
            items = dict(zip(keys, changes, strict=True))
            for watcher in watchers:
                kinds = [items[_read_key(watched, watcher.since)] for watched in watcher.watched]
                watcher.deliver(_in_feed_order(kinds), position)


HUB = Hub()


async def watch_stream(
    watched: tuple[Watched, ...], framing: Framing, opening: Opening
) -> AsyncIterator[bytes]:
    """The opening's items, then each change's, until the client goes or falls too far behind;
    keepalives while there is nothing to send."""
    watcher = Watcher(watched=watched, framing=framing, since=opening.position)
    watcher.sent.update(((item.kind, item.name), hash(item.data)) for item in opening.items)
    HUB.add(watcher)
    try:
        # The response's headers go out now, not with the first item, which may be a long while.
        yield framing.start() + (framing.error(*opening.notice) if opening.notice else b"")
        opened = [
            framing.item(item, since=opening.since, position=opening.position) for item in opening.items
        ]
        if opening.since is None:
            opened.append(framing.snapshot_end(opening.position))
        yield b"".join(opened)
        while True:
            try:
                chunk = watcher.queue.get_nowait()
            except asyncio.QueueEmpty:
                try:
                    chunk = await asyncio.wait_for(watcher.queue.get(), framing.keepalive_seconds)
                except TimeoutError:
                    # Nothing waits: the client has had every change up to the watcher's position.
                    yield framing.keepalive(watcher.since)
                    continue
            # Whatever else waits goes out in the same write.
            chunks = []
            while chunk is not None:
                chunks.append(chunk)
                if watcher.queue.empty():
                    break
                chunk = watcher.queue.get_nowait()
            if chunks:
                yield b"".join(chunks)
            if chunk is None:
                return
    finally:
        HUB.remove(watcher)
