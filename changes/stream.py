"""Watch streams (GET /robot/watch, GET /mission/watch as NDJSON; GET /events as server-sent events): a
snapshot (or, for a resuming SSE client, what it has not had), then every committed change, from the
change feed (changes.models.Change).

Served from an ASGI process (fleet.asgi): a watcher is a queue in the event loop, not a thread. One poller
per process reads the feed for all its watchers: watchers of one kind with the same filters at the same
feed position share one query and one serialization per poll, and those with the same framing too one
framed chunk, which their queues hold as one object (hundreds of watchers of a busy fleet would otherwise
hold hundreds of copies of each change). The process's queues are bounded twice: per watcher
(FLEET_WATCH_QUEUE_LINES) and together (FLEET_WATCH_QUEUE_BYTES, each shared chunk counted once; past it the
watchers furthest behind are dropped first); what a stream has written and its client not read yet, by
the size of a write (WRITE_BYTES).

A watcher goes from feed position to feed position (changes.selectors reads the feed), so it has every
committed change once; a watcher of several kinds gets one read's changes of all of them in feed order.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
import time
from collections import defaultdict, deque
from collections.abc import AsyncIterator, Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from itertools import islice
from operator import attrgetter

import orjson
from django.conf import settings
from django.db import DatabaseError, connection
from django.db.models import Model, QuerySet
from rest_framework.serializers import BaseSerializer

from access.selectors import Credential, credentials_usable
from changes.framing import Framing
from changes.selectors import Span, watch_changes, watch_resume, watch_snapshot

logger = logging.getLogger(__name__)

LAST_IMAGES = 100_000  # objects per group of watchers whose last image is kept (LastImages)
# Bytes a stream writes at once at most (whole items; one larger item alone): the HTTP server holds up to
# 32 writes per stream that its client has not read yet (granian's channel), so this bounds that too.
WRITE_BYTES = 64 * 1024
# How often the hub looks for quiet streams that are due a keepalive (SSE): a keepalive comes up to this
# much later than FLEET_EVENTS_KEEPALIVE_SECONDS after a stream's last write.
KEEPALIVE_CHECK_SECONDS = 1.0

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


@dataclass(frozen=True)
class Framed:
    """One read's items as the watchers that share the read and a framing get them: framed once, in pieces
    of at most WRITE_BYTES (whole items) that every such watcher's queue holds (the same objects)."""

    pieces: list[tuple[bytes, int]]  # (bytes, items in them)
    lines: int  # items in all

    @classmethod
    def of(cls, items: Iterable[Item], framing: Framing, *, since: str, position: str) -> Framed:
        pieces: list[tuple[bytes, int]] = []
        lines: list[bytes] = []
        size = count = 0
        for item in items:
            line = framing.item(item, since=since, position=position)
            if lines and size + len(line) > WRITE_BYTES:
                pieces.append((b"".join(lines), len(lines)))
                lines, size = [], 0
            lines.append(line)
            size += len(line)
            count += 1
        if lines:
            pieces.append((b"".join(lines), len(lines)))
        return cls(pieces=pieces, lines=count)


class Ledger:
    """The bytes a process's watcher queues hold, each chunk counted once however many queues hold it."""

    def __init__(self) -> None:
        self._held: dict[int, list] = {}  # id(chunk) -> [chunk, holders]; the chunk keeps its id unique
        self.bytes = 0

    def hold(self, chunk: bytes) -> None:
        entry = self._held.get(id(chunk))
        if entry is None:
            self._held[id(chunk)] = [chunk, 1]
            self.bytes += len(chunk)
        else:
            entry[1] += 1

    def release(self, chunk: bytes) -> None:
        entry = self._held[id(chunk)]
        entry[1] -= 1
        if not entry[1]:
            del self._held[id(chunk)]
            self.bytes -= len(chunk)


class LastImages:
    """The last image (hashed) of each object of one kind that watchers were sent, so that a change that
    shows nothing new (a column the API does not show) is sent to none of them. One per group of watchers
    (a kind and its filters), not one per watcher: hundreds of watchers of a fleet that creates missions
    all day would otherwise each keep a digest of every mission. Past LAST_IMAGES objects the ones that
    changed longest ago are forgotten: a change of one of those is sent even if it shows nothing new."""

    def __init__(self, digests: dict[str, int] | None = None) -> None:
        self._digests: dict[str, int] = digests or {}  # name -> hash of its JSON; least recent first

    def fresh(self, items: Iterable[Item]) -> list[Item]:
        """The items (in order) that do not repeat their object's last image; those are remembered."""
        digests, fresh = self._digests, []
        for item in items:
            digest = hash(item.data)
            if digests.pop(item.name, None) != digest:
                fresh.append(item)
            digests[item.name] = digest
        self._forget()
        return fresh

    def remember(self, other: LastImages) -> None:
        """Take in what another (a new watcher's, up to the same position) knows."""
        self._digests.update(other._digests)
        self._forget()

    def _forget(self) -> None:
        if len(self._digests) > LAST_IMAGES:
            for name in list(islice(self._digests, len(self._digests) - LAST_IMAGES // 2)):
                del self._digests[name]


GroupKey = tuple[str, tuple]  # (kind, filters): the watchers that see the same objects


def _group_key(watched: Watched) -> GroupKey:
    return watched.kind, watched.filters


@dataclass(eq=False)
class Watcher:
    watched: tuple[Watched, ...]
    framing: Framing
    since: str  # the feed position this watcher has had every change up to
    ledger: Ledger = field(default_factory=Ledger)  # the process's (Hub.ledger): what all queues hold
    # Chunks (None: the stream ends), each with the number of lines in it.
    queue: deque[tuple[bytes | None, int]] = field(default_factory=deque)
    waiting: int = 0  # lines in the queue
    arrived: asyncio.Event = field(default_factory=asyncio.Event)
    # Until its first poll (its snapshot's position is its own), the last images this watcher was sent,
    # per kind; then None: its group's (Hub) are the same from there on.
    own: dict[str, LastImages] | None = None
    dropped: bool = False
    # What the stream's request authenticated with (None: it needed nothing); the stream ends once that
    # would no longer authenticate a request (Hub).
    credential: Credential | None = None
    wrote_at: float = field(default_factory=time.monotonic)  # when the stream last had something to write

    def deliver(self, framed: Framed, position: str) -> None:
        """Queue one read's items (the changes after `since` up to `position`); the watcher is then at
        `position`. A watcher too far behind is told and dropped."""
        self.since = position
        if self.dropped or not framed.lines:
            return
        if self.waiting + framed.lines > settings.WATCH_QUEUE_LINES:
            self.drop(
                "watcher_behind",
                f"More than {settings.WATCH_QUEUE_LINES} changes waited for this watcher: it is dropped. "
                "Watch again for a new snapshot.",
                resumable=False,
            )
            return
        for piece, lines in framed.pieces:
            self._put(piece, lines)

    def drop(self, error: str, detail: str, *, resumable: bool) -> None:
        """End the stream with an error in place of whatever still waits: the client watches again (SSE:
        resuming where it was if `resumable`, else with a new snapshot)."""
        self.dropped = True
        self.close()
        self._put(self.framing.error(error, detail, resumable=resumable), 0)
        self._put(None, 0)

    def close(self) -> None:
        """Let go of whatever waits (the stream is over)."""
        while self.queue:
            self._took(self.queue.popleft())

    def keep_alive(self, now: float) -> None:
        """Queue a keepalive if the framing has them and the stream has been quiet for its interval.

        The hub asks every watcher once a KEEPALIVE_CHECK_SECONDS: a timeout on each wait for changes cost
        every wake-up of every stream a task and a timer (twice a plain wait's CPU), and hundreds of
        streams left thousands of cancelled timers in the event loop's heap."""
        interval = self.framing.keepalive_seconds
        if interval is None or self.queue or self.dropped or now - self.wrote_at < interval:
            return
        # Nothing waits: the client has had every change up to the watcher's position.
        self._put(self.framing.keepalive(self.since), 0)

    async def take(self) -> list[bytes | None]:
        """What waits, up to WRITE_BYTES (after a wait for something): chunks, then None if the stream
        ends."""
        if not self.queue:
            self.arrived.clear()
            await self.arrived.wait()
        self.wrote_at = time.monotonic()
        taken: list[bytes | None] = []
        size = 0
        while self.queue:
            chunk = self.queue[0][0]
            if chunk is not None and taken and size + len(chunk) > WRITE_BYTES:
                break
            taken.append(self._took(self.queue.popleft()))
            if chunk is None:
                break
            size += len(chunk)
        return taken

    def _put(self, chunk: bytes | None, lines: int) -> None:
        # Changes only: the error line that ends a dropped stream is small and one per stream.
        if lines:
            self.ledger.hold(chunk)
            self.waiting += lines
        self.queue.append((chunk, lines))
        self.arrived.set()

    def _took(self, entry: tuple[bytes | None, int]) -> bytes | None:
        chunk, lines = entry
        if lines:
            self.ledger.release(chunk)
            self.waiting -= lines
        return chunk


@dataclass(frozen=True)
class Opening:
    """What a stream sends before the changes the poller brings: a snapshot's items (`since` None), or
    those of a resume, read after `since`; the watcher goes on from `position`."""

    position: str
    items: list[Item]
    since: str | None = None
    notice: tuple[str, str] | None = None  # an error the client is told first, (error, detail)

    def last_images(self) -> dict[str, LastImages]:
        """Per kind, the images it sends: what the watcher's first read is judged by."""
        kinds: dict[str, dict[str, int]] = {}
        for item in self.items:
            kinds.setdefault(item.kind, {})[item.name] = hash(item.data)
        return defaultdict(LastImages, {kind: LastImages(digests) for kind, digests in kinds.items()})


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
        self.ledger = Ledger()
        self._groups: dict[GroupKey, LastImages] = {}  # those of the watchers' groups
        self._task: asyncio.Task[None] | None = None
        self._keepalive_task: asyncio.Task[None] | None = None
        self._credentials_checked = time.monotonic()
        # One thread, one database connection: the poller's reads never wait for a request's thread.
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="watch-poller")

    def add(self, watcher: Watcher) -> None:
        self.watchers.add(watcher)
        loop = asyncio.get_running_loop()
        if self._task is None or self._task.done():
            self._task = loop.create_task(self._poll_forever())
        if self._keepalive_task is None or self._keepalive_task.done():
            self._keepalive_task = loop.create_task(self._keep_alive_forever())

    def remove(self, watcher: Watcher) -> None:
        self.watchers.discard(watcher)
        watcher.close()

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
            self.deliver(watchers, dict(zip(keys, changes, strict=True)), position)
            if time.monotonic() - self._credentials_checked >= settings.STREAM_CREDENTIALS_CHECK_SECONDS:
                await self._end_unauthenticated(loop)

    async def _keep_alive_forever(self) -> None:
        """Keepalives for quiet streams, apart from the poller: they go on while a read of the feed waits
        for PostgreSQL."""
        while self.watchers:
            await asyncio.sleep(KEEPALIVE_CHECK_SECONDS)
            now = time.monotonic()
            for watcher in self.watchers:
                watcher.keep_alive(now)

    async def _end_unauthenticated(self, loop: asyncio.AbstractEventLoop) -> None:
        """End the streams whose token was revoked or expired, or whose session ended (a logout, its
        expiry, its user no longer staff): a stream is authenticated when it opens, and may stay open for
        days. One read for all of the process's streams."""
        self._credentials_checked = time.monotonic()
        credentials = {watcher.credential for watcher in self.watchers if watcher.credential}
        if not credentials:
            return
        try:
            usable = await loop.run_in_executor(self._executor, credentials_usable, credentials)
        except DatabaseError:
            logger.warning("The streams' credentials could not be checked; retrying", exc_info=True)
            await loop.run_in_executor(self._executor, connection.close)
            return
        for watcher in self.watchers:
            # Only those checked: a watcher may have come meanwhile.
            if watcher.credential in credentials and watcher.credential not in usable and not watcher.dropped:
                watcher.drop(
                    "not_authenticated",
                    "The token this stream was opened with was revoked or has expired, or the session "
                    "has ended: authenticate again and watch again.",
                    resumable=True,
                )

    def deliver(self, watchers: list[Watcher], items: dict[ReadKey, list[Item]], position: str) -> None:
        """One poll's items to each watcher, framed once per (reads, framing); then, past
        FLEET_WATCH_QUEUE_BYTES held in all, the watchers furthest behind are dropped until it is not.

        The watchers past their first poll are all at the same position: their groups' last images
        judge what is new to them. A new watcher's own (from its snapshot) judge its first read; the
        group takes them in after, when they are at the same position: first the others', so that
        these do not judge the others' read by images of its end."""
        framed: dict[tuple, Framed] = {}
        fresh: dict[ReadKey, list[Item]] = {}
        in_use = {
            _group_key(watched) for watcher in (*self.watchers, *watchers) for watched in watcher.watched
        }
        self._groups = {key: self._groups.get(key) or LastImages() for key in in_use}
        joined = [watcher for watcher in watchers if watcher.own is None]
        for watcher in joined:
            read_keys = tuple(_read_key(watched, watcher.since) for watched in watcher.watched)
            shared = (read_keys, type(watcher.framing))
            if shared not in framed:
                for key in read_keys:
                    if key not in fresh:
                        fresh[key] = self._groups[key[:2]].fresh(items[key])
                kinds = [fresh[key] for key in read_keys]
                framed[shared] = Framed.of(
                    _in_feed_order(kinds), watcher.framing, since=watcher.since, position=position
                )
            watcher.deliver(framed[shared], position)
        for watcher in watchers:
            if watcher.own is None:
                continue
            own, watcher.own = watcher.own, None
            kinds = [
                own[watched.kind].fresh(items[_read_key(watched, watcher.since)])
                for watched in watcher.watched
            ]
            watcher.deliver(
                Framed.of(_in_feed_order(kinds), watcher.framing, since=watcher.since, position=position),
                position,
            )
            for watched in watcher.watched:
                self._groups[_group_key(watched)].remember(own[watched.kind])
        behind = sorted((watcher for watcher in watchers if watcher.waiting), key=attrgetter("waiting"))
        while self.ledger.bytes > settings.WATCH_QUEUE_BYTES and behind:
            behind.pop().drop(
                "watcher_behind",
                f"This server's watchers had more than {settings.WATCH_QUEUE_BYTES} bytes of changes "
                "waiting and this one was among those furthest behind: it is dropped. "
                "Watch again for a new snapshot.",
                resumable=False,
            )


HUB = Hub()


async def watch_stream(
    watched: tuple[Watched, ...], framing: Framing, opening: Opening, credential: Credential | None
) -> AsyncIterator[bytes]:
    """The opening's items, then each change's, until the client goes, falls too far behind or its
    credential no longer authenticates; keepalives while there is nothing to send."""
    watcher = Watcher(
        watched=watched,
        framing=framing,
        since=opening.position,
        ledger=HUB.ledger,
        own=opening.last_images(),
        credential=credential,
    )
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
            taken = await watcher.take()
            # Whatever waited goes out in one write.
            chunks = [chunk for chunk in taken if chunk is not None]
            if chunks:
                yield chunks[0] if len(chunks) == 1 else b"".join(chunks)
            if taken[-1] is None:
                return
    finally:
        HUB.remove(watcher)
