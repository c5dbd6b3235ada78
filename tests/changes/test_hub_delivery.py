"""How a process's poller hands one poll's changes to its watchers (changes.stream.Hub.deliver): framed once
for the watchers that share a read and a framing, their queues holding the one chunk; writes of bounded
size; the bytes of all queues bounded together, the watchers furthest behind dropped first. No database:
the items are given."""

import asyncio

import orjson
import pytest
from pytest_django.fixtures import Settings

from changes.framing import Framing, Ndjson, ServerSentEvents
from changes.stream import Hub, Item, Opening, Watched, Watcher
from robots.api.serializers import RobotSerializer

POSITION = "10:10:"


def _watched(filters: tuple = ()) -> Watched:
    return Watched(kind="robot", query=lambda: None, filters=filters, serializer=RobotSerializer)


def _item(change: int, name: str, battery: int) -> Item:
    data = orjson.dumps({"name": name, "status": {"battery_level": battery}})
    return Item(change=change, kind="robot", name=name, data=data)


def _watcher(hub: Hub, watched: Watched, framing: Framing | None = None) -> Watcher:
    return Watcher(watched=(watched,), framing=framing or Ndjson(), since="5:5:", ledger=hub.ledger)


def _poll(hub: Hub, watchers: list[Watcher], items: dict[Watched, list[Item]], position: str) -> None:
    """One poll: each watcher's read keyed as the poller keys it, at the watchers' common position."""
    since = watchers[0].since
    hub.deliver(watchers, {(w.kind, w.filters, since): each for w, each in items.items()}, position)


def _taken(watcher: Watcher) -> list[bytes | None]:
    return asyncio.run(watcher.take())


def test_watchers_that_share_a_read_and_a_framing_hold_one_chunk() -> None:
    hub, watched = Hub(), _watched()
    ndjson = [_watcher(hub, watched) for _ in range(3)]
    sse = [_watcher(hub, watched, ServerSentEvents()) for _ in range(2)]
    items = [_item(11, "r1", 50), _item(12, "r2", 60)]

    _poll(hub, ndjson + sse, {watched: items}, POSITION)

    chunks = [watcher.queue[0][0] for watcher in ndjson + sse]
    assert chunks[0] == items[0].data + b"\n" + items[1].data + b"\n"
    assert chunks[0] is chunks[1] is chunks[2]
    assert chunks[3] is chunks[4] and chunks[3] is not chunks[0]
    assert chunks[3].count(b"event: robot\n") == 2
    # Each distinct chunk is counted once, however many queues hold it.
    assert hub.ledger.bytes == len(chunks[0]) + len(chunks[3])
    assert all(watcher.since == POSITION for watcher in ndjson + sse)


def test_other_filters_are_another_read_and_another_chunk() -> None:
    hub, everyone, one = Hub(), _watched(), _watched((("names", ("r1",)),))
    first, second = _watcher(hub, everyone), _watcher(hub, one)

    _poll(
        hub,
        [first, second],
        {everyone: [_item(11, "r1", 50), _item(12, "r2", 1)], one: [_item(11, "r1", 50)]},
        POSITION,
    )

    assert _taken(first) == [_item(11, "r1", 50).data + b"\n" + _item(12, "r2", 1).data + b"\n"]
    assert _taken(second) == [_item(11, "r1", 50).data + b"\n"]


def test_a_change_that_shows_nothing_new_is_no_line() -> None:
    hub, watched = Hub(), _watched()
    watchers = [_watcher(hub, watched) for _ in range(2)]
    _poll(hub, watchers, {watched: [_item(11, "r1", 50), _item(12, "r2", 60)]}, POSITION)
    assert all(_taken(watcher) for watcher in watchers)

    # r2 written again as it was (a column the API does not show), r1 changed twice, then back: all seen.
    _poll(hub, watchers, {watched: [_item(13, "r2", 60), _item(14, "r1", 51), _item(15, "r1", 50)]}, "20:20:")

    lines = [_item(14, "r1", 51).data + b"\n" + _item(15, "r1", 50).data + b"\n"]
    assert [_taken(watcher) for watcher in watchers] == [lines, lines]
    assert all(watcher.since == "20:20:" for watcher in watchers)


def _new_watcher(hub: Hub, watched: Watched, snapshot: list[Item], since: str) -> Watcher:
    """A watcher whose stream has just sent `snapshot`, read at `since`."""
    opening = Opening(position=since, items=snapshot)
    return Watcher(
        watched=(watched,), framing=Ndjson(), since=since, ledger=hub.ledger, own=opening.last_images()
    )


def test_a_new_watcher_is_judged_by_its_snapshot_and_then_joins_the_others() -> None:
    hub, watched = Hub(), _watched()
    old = _watcher(hub, watched)
    _poll(hub, [old], {watched: [_item(11, "r1", 50)]}, "11:11:")
    _taken(old)
    # r1 changed to 51 after the old watcher's position, before the new one's snapshot, which shows it.
    new = _new_watcher(hub, watched, [_item(0, "r1", 51)], since="12:12:")

    hub.deliver(
        [old, new],
        {
            ("robot", (), "11:11:"): [_item(12, "r1", 51), _item(13, "r2", 1)],
            ("robot", (), "12:12:"): [_item(13, "r2", 1)],
        },
        "13:13:",
    )

    # Each judged by what it had: the old one had r1 at 50, the new one at 51.
    assert _taken(old) == [_item(12, "r1", 51).data + b"\n" + _item(13, "r2", 1).data + b"\n"]
    assert _taken(new) == [_item(13, "r2", 1).data + b"\n"]
    # From here on both are at one position and share: r1 again at 51 is nothing new to either.
    _poll(hub, [old, new], {watched: [_item(14, "r1", 51), _item(15, "r2", 2)]}, "15:15:")
    assert _taken(old) == _taken(new) == [_item(15, "r2", 2).data + b"\n"]
    assert not old.queue and not new.queue


def test_the_last_images_kept_are_bounded(monkeypatch) -> None:
    monkeypatch.setattr("changes.stream.LAST_IMAGES", 10)
    hub, watched = Hub(), _watched()
    watcher = _watcher(hub, watched)
    _poll(hub, [watcher], {watched: [_item(number, f"r{number:02}", 50) for number in range(1, 12)]}, "1:1:")
    _taken(watcher)

    # r01 was the longest ago and is forgotten: its repeat is sent; r11's is not.
    _poll(hub, [watcher], {watched: [_item(12, "r01", 50), _item(13, "r11", 50)]}, "2:2:")

    assert _taken(watcher) == [_item(12, "r01", 50).data + b"\n"]


def test_a_stream_writes_at_most_write_bytes_at_once(monkeypatch) -> None:
    line = len(_item(0, "r10", 10).data) + 1  # every name and battery level here has two digits
    monkeypatch.setattr("changes.stream.WRITE_BYTES", 3 * line)
    hub, watched = Hub(), _watched()
    first, second = _watcher(hub, watched), _watcher(hub, watched)
    items = [_item(number, f"r{number}", 10 + number) for number in range(10, 18)]  # 8 lines

    _poll(hub, [first, second], {watched: items}, POSITION)

    # Pieces of whole lines, shared by the two queues.
    assert [lines for _, lines in first.queue] == [3, 3, 2]
    assert all(a[0] is b[0] for a, b in zip(first.queue, second.queue, strict=True))
    _poll(hub, [first, second], {watched: [_item(18, "r18", 28)]}, "20:20:")
    writes = [_taken(first) for _ in range(3)]
    # A write takes whole pieces while they fit: the last piece of a poll and the next poll's go together.
    assert [sum(len(chunk) for chunk in write) for write in writes] == [3 * line, 3 * line, 3 * line]
    assert b"".join(chunk for write in writes for chunk in write) == b"".join(
        item.data + b"\n" for item in [*items, _item(18, "r18", 28)]
    )
    assert not first.queue and first.waiting == 0


def test_what_a_stream_takes_or_leaves_behind_is_let_go() -> None:
    hub, watched = Hub(), _watched()
    reader, leaver = _watcher(hub, watched), _watcher(hub, watched)
    _poll(hub, [reader, leaver], {watched: [_item(11, "r1", 50)]}, POSITION)
    _poll(hub, [reader, leaver], {watched: [_item(12, "r1", 51)]}, "20:20:")
    assert reader.waiting == leaver.waiting == 2

    assert len(_taken(reader)) == 2  # both chunks in one take: one write
    assert reader.waiting == 0
    assert hub.ledger.bytes > 0  # the one that left has not read them yet
    hub.remove(leaver)  # its stream ended
    assert hub.ledger.bytes == 0


def test_past_the_bytes_bound_the_watchers_furthest_behind_are_dropped(settings) -> None:
    hub, watched = Hub(), _watched()
    slow, slower, reader = (_watcher(hub, watched) for _ in range(3))
    everyone = [slow, slower, reader]
    line = len(_item(0, "r1", 10).data) + 1  # every battery level here has two digits
    settings.WATCH_QUEUE_BYTES = 10 * line
    _poll(hub, everyone, {watched: [_item(1, "r1", 11), _item(2, "r2", 11)]}, "1:1:")
    assert _taken(slower) and _taken(reader)
    for change in range(3, 11):  # 8 polls of one line each: slow has 10 lines waiting, slower 8, reader 0
        _poll(hub, everyone, {watched: [_item(change, "r1", 10 + change)]}, f"{change}:{change}:")
        _taken(reader)
    assert hub.ledger.bytes == 10 * line
    assert not any(watcher.dropped for watcher in everyone)

    _poll(hub, everyone, {watched: [_item(11, "r1", 21)]}, "11:11:")

    # Shared chunks: dropping `slow` frees its first poll's two lines; the rest are `slower`'s too.
    assert slow.dropped and not slower.dropped and not reader.dropped
    taken = _taken(slow)
    assert taken[-1] is None
    error = orjson.loads(taken[0])
    assert error["error"] == "watcher_behind"
    assert f"more than {10 * line} bytes" in error["detail"]
    assert hub.ledger.bytes <= 10 * line
    assert _taken(reader) == [_item(11, "r1", 21).data + b"\n"]


@pytest.mark.parametrize("framing", [Ndjson(), ServerSentEvents()], ids=["ndjson", "sse"])
def test_past_the_lines_bound_a_watcher_is_dropped_with_a_new_snapshot_to_come(settings, framing) -> None:
    hub, watched = Hub(), _watched()
    watcher = _watcher(hub, watched, framing)
    settings.WATCH_QUEUE_LINES = 3
    _poll(hub, [watcher], {watched: [_item(1, "r1", 1), _item(2, "r2", 1), _item(3, "r3", 1)]}, "1:1:")
    assert not watcher.dropped

    _poll(hub, [watcher], {watched: [_item(4, "r1", 2)]}, "2:2:")

    taken = _taken(watcher)
    assert watcher.dropped and taken[-1] is None and len(taken) == 2
    assert b"watcher_behind" in taken[0]
    if isinstance(framing, ServerSentEvents):
        assert taken[0].startswith(b"id: \n")  # not resumable: the reconnection asks for a snapshot
    assert hub.ledger.bytes == 0


def test_a_quiet_event_stream_gets_a_keepalive_with_its_position_once_its_interval_passed(
    settings: Settings,
) -> None:
    settings.EVENTS_KEEPALIVE_SECONDS = 15.0
    hub, watched = Hub(), _watched()
    sse, ndjson = _watcher(hub, watched, ServerSentEvents()), _watcher(hub, watched)
    quiet_since = sse.wrote_at

    for watcher in (sse, ndjson):
        watcher.keep_alive(quiet_since + 14.9)
    assert not sse.queue

    for watcher in (sse, ndjson):
        watcher.keep_alive(quiet_since + 15.0)
    assert _taken(sse) == [b": keepalive\nid: 5:5:\n\n"]  # everything up to its position delivered
    assert not ndjson.queue  # NDJSON has no keepalives

    sse.keep_alive(sse.wrote_at + 1.0)  # the interval counts from the keepalive written
    assert not sse.queue


def test_a_stream_with_something_to_write_gets_no_keepalive(settings: Settings) -> None:
    settings.EVENTS_KEEPALIVE_SECONDS = 15.0
    hub, watched = Hub(), _watched()
    sse = _watcher(hub, watched, ServerSentEvents())
    _poll(hub, [sse], {watched: [_item(11, "r1", 50)]}, POSITION)

    sse.keep_alive(sse.wrote_at + 60)

    assert len(sse.queue) == 1 and b"keepalive" not in sse.queue[0][0]


def test_waiting_for_changes_schedules_no_timer() -> None:
    """A timeout on every stream's every wait cost a task and a timer per wake-up; the hub's one loop
    sends the keepalives instead."""
    hub, watched = Hub(), _watched()
    sse = _watcher(hub, watched, ServerSentEvents())

    async def wait_then_deliver() -> tuple[int, list[bytes | None]]:
        loop = asyncio.get_running_loop()
        waiting = loop.create_task(sse.take())
        await asyncio.sleep(0)  # the watcher now waits
        timers = len(loop._scheduled)  # type: ignore[attr-defined]
        _poll(hub, [sse], {watched: [_item(11, "r1", 50)]}, POSITION)
        return timers, await waiting

    timers, taken = asyncio.run(wait_then_deliver())

    assert timers == 0
    assert taken[0].count(b"event: robot\n") == 1
