"""Hostile messages on every topic the bridge reads, against the real PostgreSQL and Redis: each is dropped or
ignored and counted under its reason, stores nothing, and the rest of its batch is handled."""

import itertools
import json
import logging
import uuid
from collections.abc import Callable
from typing import Any

import orjson
import pytest
from django.db import connection
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robots import livestate
from robots.models import Robot
from tests.workers.bridge.hostile import SUBSCRIBED, Case, corpus, history
from tests.workers.bridge.messages import connection_message, state_message, step_requested, topic
from tests.workers.bridge.rows import held
from vda5050.codec import parse
from vda5050.errors import ProtocolError
from vda5050.models import ConnectionState
from vda5050.topics import Topic
from workers import metrics
from workers.bridge.gate import Drop, Ignored
from workers.bridge.loop import Bridge

MakeRobot = Callable[..., Robot]
CASES = corpus("victim", "stranger")  # ids and reasons only: the tests build their own with real serials


def counters() -> dict[str, int]:
    """The dropped and ignored message counters, by Redis field."""
    return {
        field.decode(): int(value)
        for field, value in livestate.client().hgetall(metrics.COUNTERS).items()
        if field.startswith((metrics.MESSAGES_INVALID.encode(), metrics.MESSAGES_IGNORED.encode()))
    }


def counted(before: dict[str, int]) -> dict[str, int]:
    """What the counters counted since `before`."""
    return {
        field: value - before.get(field, 0)
        for field, value in counters().items()
        if value != before.get(field)
    }


def field(counter: str, topic_label: str, reason: str) -> str:
    return f"{counter}|reason={reason}|topic={topic_label}"


def stored(robot: Robot) -> dict[str, Any]:
    """Everything stored about the robot: its row, its live state in Redis, whether and when it was heard."""
    client = livestate.client()
    return {
        "row": Robot.objects.filter(name=robot.name).values().get(),
        "live": client.hgetall(livestate.robot_key(robot.name)),
        "online": client.sismember(livestate.ONLINE_SET, robot.name),
        "last_seen": client.zscore(livestate.LAST_SEEN, robot.name),
    }


@pytest.fixture
def victim(bridge: Bridge, make_robot: MakeRobot) -> Robot:
    """A robot the bridge heard from on every topic (`hostile.history`), all of it written."""
    robot = make_robot("victim")
    bridge.directory.reload()
    bridge.handle(history(robot.serial_number))
    bridge.status_writer.flush()
    step_requested(robot)
    return robot


@pytest.fixture
def bystander(make_robot: MakeRobot, bridge: Bridge) -> Robot:
    robot = make_robot("bystander")
    bridge.directory.reload()
    return robot


def test_the_history_is_stored_as_the_hostile_cases_expect(victim: Robot) -> None:
    row = Robot.objects.get(name=victim.name)
    assert (row.online, row.battery_level, row.pose_x, row.factsheet["typeSpecification"]["seriesName"]) == (
        True,
        55.0,
        7.0,  # the visualization, newer than the state
        "carter",
    )


def _own(case: Case, victim: Robot, stranger: str) -> Case:
    """The case built for this test's robots."""
    (built,) = [c for c in corpus(victim.serial_number, stranger) if c.id == case.id]
    return built


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_a_hostile_message_is_counted_changes_nothing_and_the_rest_of_its_batch_is_handled(
    bridge: Bridge, victim: Robot, bystander: Robot, case: Case
) -> None:
    stranger = f"stranger-{uuid.uuid4().hex[:8]}"
    case = _own(case, victim, stranger)
    before, counters_before = stored(victim), counters()
    good = state_message(bystander, battery=33.0)

    bridge.handle([(case.topic, case.payload), good])
    bridge.status_writer.flush()

    assert counted(counters_before) == {field(case.counter, case.label, case.reason): 1}
    assert stored(victim) == before
    assert not step_requested(victim)
    assert not Robot.objects.filter(serial_number=stranger).exists()
    assert livestate.latest_state(bystander.name).payload == good[1]
    assert Robot.objects.get(name=bystander.name).battery_level == 33.0


def test_the_corpus_has_every_class_on_every_topic() -> None:
    by_topic = {kind: {(c.counter, c.reason) for c in CASES if c.label == kind} for kind in SUBSCRIBED}
    every = {(metrics.MESSAGES_INVALID, reason) for reason in Drop if reason != Drop.REFUSED} | {
        (metrics.MESSAGES_IGNORED, reason) for reason in Ignored
    }
    assert by_topic == dict.fromkeys(SUBSCRIBED, every)


def test_a_replayed_disconnection_does_not_take_a_robot_offline_but_a_newer_one_does(
    bridge: Bridge, victim: Robot
) -> None:
    # The history: CONNECTIONBROKEN (headerId 1, at 1 s), then a state that brought the robot back.
    bridge.handle([connection_message(victim, ConnectionState.CONNECTIONBROKEN, header_id=1, at=1.0)])
    assert Robot.objects.get(name=victim.name).online is True

    bridge.handle([connection_message(victim, ConnectionState.CONNECTIONBROKEN, header_id=2, at=5.0)])
    assert Robot.objects.get(name=victim.name).online is False


def test_a_last_will_older_than_the_online_message_before_it_takes_the_robot_offline(
    bridge: Bridge, victim: Robot
) -> None:
    """The broker sends the will with the header the robot gave it on connecting, before its ONLINE."""
    bridge.handle([connection_message(victim, ConnectionState.ONLINE, header_id=3, at=6.0)])
    bridge.handle([connection_message(victim, ConnectionState.CONNECTIONBROKEN, header_id=2, at=5.0)])

    assert Robot.objects.get(name=victim.name).online is False


@pytest.mark.django_db(transaction=True)  # autocommit, as the bridge runs: a refused write aborts no batch
def test_a_factsheet_the_database_refuses_is_counted_and_the_rest_of_the_batch_is_handled(
    bridge: Bridge, make_robot: MakeRobot
) -> None:
    robot, bystander = make_robot(), make_robot()
    bridge.directory.reload()
    factsheet = next(m for m in history(robot.serial_number) if m[0].endswith("/factsheet"))
    good = state_message(bystander)
    counters_before = counters()

    with held("SELECT 1 FROM robots_robot WHERE name = %s FOR UPDATE", [robot.name]):
        with connection.cursor() as cursor:
            cursor.execute("SET lock_timeout = '50ms'")  # the write fails, as it would with PostgreSQL away
        bridge.handle([factsheet, good])

    assert counted(counters_before) == {field(metrics.MESSAGES_INVALID, "factsheet", Drop.REFUSED): 1}
    assert Robot.objects.get(name=robot.name).factsheet is None
    assert livestate.latest_state(bystander.name).payload == good[1]


@pytest.mark.parametrize(
    "text",
    ["[" * 1000 + "]" * 1000, '{"note": "stuck\\u0000here"}'],
    ids=["nested-deeper-than-the-codec-allows", "nul-in-the-json-text"],
)
def test_a_user_info_whose_json_cannot_be_stored_is_kept_as_text(
    bridge: Bridge, victim: Robot, bystander: Robot, text: str
) -> None:
    topic_name, payload = state_message(victim, header_id=2, at=10.0)
    message = orjson.loads(payload)
    message["information"] = [{"infoType": "user_info", "infoDescription": text, "infoLevel": "INFO"}]

    bridge.handle([(topic_name, orjson.dumps(message)), state_message(bystander, battery=33.0)])
    bridge.status_writer.flush()

    assert Robot.objects.get(name=victim.name).info_messages == text
    assert Robot.objects.get(name=bystander.name).battery_level == 33.0


def test_a_flood_of_dropped_messages_logs_one_line_per_topic_and_reason(
    bridge: Bridge, victim: Robot, caplog: pytest.LogCaptureFixture
) -> None:
    junk = [(topic(victim, "state"), b"junk")] * 50 + [(topic(victim, "factsheet"), b"[]")] * 50

    with caplog.at_level(logging.INFO, logger="workers.bridge"):
        bridge.handle(junk)
        bridge.handle(junk)

    lines = [record.getMessage() for record in caplog.records]
    assert len(lines) == 2, lines
    assert any("(not_json)" in line for line in lines) and any("(not_object)" in line for line in lines)


# --- property: whatever arrives, the bridge goes on ------------------------------------------------------

# Beyond what VDA 5050 allows too: integers past 64 bits, NaN and infinities (which json.dumps writes).
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=10), children, max_size=4)
    ),
    max_leaves=20,
)


@st.composite
def payloads(draw: st.DrawFn, good: dict[str, bytes]) -> tuple[str, bytes]:
    """A topic the bridge reads and what arrives on it: random bytes, random JSON, or one of the robot's good
    messages with a field changed, removed or added."""
    kind = draw(st.sampled_from(SUBSCRIBED))
    how = draw(st.sampled_from(["bytes", "json", "mutated"]))
    if how == "bytes":
        return kind, draw(st.binary(min_size=1, max_size=200))
    if how == "json":
        return kind, json.dumps(draw(JSON)).encode()
    message = orjson.loads(good[kind])
    key = draw(st.sampled_from(sorted(message)) | st.text(max_size=10))
    if draw(st.booleans()):
        message.pop(key, None)
    else:
        message[key] = draw(JSON)
    return kind, json.dumps(message).encode()


@pytest.fixture
def robots(bridge: Bridge, make_robot: MakeRobot) -> tuple[Robot, Robot, dict[str, bytes]]:
    """A victim after its history, a bystander, and the victim's good messages by topic."""
    victim, bystander = make_robot("victim"), make_robot("bystander")
    bridge.directory.reload()
    good = history(victim.serial_number)
    bridge.handle(good)
    bridge.status_writer.flush()
    return victim, bystander, {name.rsplit("/", 1)[-1]: payload for name, payload in good}


@settings(
    max_examples=100,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_whatever_arrives_is_either_a_valid_message_or_counted_and_changes_nothing(
    bridge: Bridge, robots: tuple[Robot, Robot, dict[str, bytes]], data: st.DataObject
) -> None:
    victim, bystander, good = robots
    kind, payload = data.draw(payloads(good))
    header_id = next(_bystander_header_ids)
    state = state_message(bystander, header_id=header_id, at=header_id)
    before, counters_before = stored(victim), counters()

    bridge.handle([(topic(victim, kind), payload), state])
    bridge.status_writer.flush()

    assert livestate.latest_state(bystander.name).payload == state[1]
    if not _readable(kind, payload, victim):
        assert sum(counted(counters_before).values()) == 1
        assert stored(victim) == before


_bystander_header_ids = itertools.count(1)


def _readable(kind: str, payload: bytes, robot: Robot) -> bool:
    """Whether the message is one the bridge takes (as far as parsing and the header's robot go)."""
    try:
        message = parse(Topic(kind), payload)
    except ProtocolError:
        return False
    return (
        message.serial_number in (None, robot.serial_number)
        and message.manufacturer in (None, robot.manufacturer)
        and b"\\u0000" not in payload
    )
