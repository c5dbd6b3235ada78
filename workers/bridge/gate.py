"""The bridge's message gate: what a message must be for the bridge to take it.

`read` turns a topic and payload into a `Received` message of a known robot, or raises `Dropped` saying
why not (`Drop`, the `reason` of `messages_invalid`); `Ignored` names why a well-formed message older than
the robot's last on its topic is left out (`messages_ignored`), and `DropLog` keeps the log of both short.
"""

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

import orjson
from django.conf import settings

from dispatch.held import StateDigest, state_digest
from vda5050.codec import parse_connection, parse_factsheet, parse_state, parse_visualization
from vda5050.errors import PayloadError, ProtocolError
from vda5050.models import Connection, ConnectionState, Factsheet, State, Visualization
from vda5050.topics import Topic, major_version_of, parse_topic
from vda5050.versions import supported_version
from workers import tuning
from workers.bridge.directory import RobotDirectory

logger = logging.getLogger(__name__)

TOPIC_NAMES = frozenset(topic.value for topic in Topic)
NUL_ESCAPE = b"\\u0000"  # how JSON writes a NUL character, which PostgreSQL stores in neither text nor jsonb


class Drop(StrEnum):
    """Why a message was dropped unread: the `reason` of `messages_invalid` (README, Metrics). The values
    of vda5050.errors.PayloadProblem are among them."""

    TOPIC = "topic"  # not <interfaceName>/<vN>/<manufacturer>/<serialNumber>/<a topic the bridge reads>
    UNKNOWN_ROBOT = "unknown_robot"  # no robot has these topic levels
    TOO_LARGE = "too_large"  # over FLEET_MQTT_MAX_PAYLOAD_BYTES, dropped before parsing
    NOT_UTF8 = "not_utf8"
    NOT_JSON = "not_json"  # includes NaN, Infinity and numbers beyond a double
    NOT_OBJECT = "not_object"  # JSON, but null, a number, a string or a list
    TOO_DEEP = "too_deep"  # nested deeper than vda5050.codec.MAX_NESTING
    SCHEMA = "schema"  # a field missing, of the wrong type or out of range
    FUTURE = "future"  # timestamped more than tuning.FUTURE_TOLERANCE_SECONDS ahead of this host's clock
    NUL = "nul"  # a NUL character in a string
    HEADER_MISMATCH = "header_mismatch"  # the header's manufacturer or serialNumber are not the topic's
    REFUSED = "refused"  # PostgreSQL refused what the message holds (a factsheet)


class Ignored(StrEnum):
    """Why a well-formed message was ignored: the `reason` of `messages_ignored`."""

    REPLAYED = "replayed"  # the timestamp and headerId of the newest message on the topic, again
    STALE = "stale"  # older (timestamp, then headerId) than the newest message on the topic


class Dropped(Exception):
    """A message the bridge does not take, and why."""

    def __init__(self, reason: Drop, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


@dataclass(frozen=True)
class Received:
    """A message the bridge read, of a known robot; `order` is its (timestamp ms, headerId), None for a
    visualization without them."""

    name: str
    kind: Topic
    message: State | Connection | Factsheet | Visualization
    payload: bytes
    order: tuple[int, int] | None
    digest: StateDigest | None = None  # a state's
    major_version: str = ""  # of the topic it came on


PARSERS: dict[Topic, Callable[[bytes], State | Connection | Factsheet | Visualization]] = {
    Topic.STATE: parse_state,
    Topic.CONNECTION: parse_connection,
    Topic.FACTSHEET: parse_factsheet,
    Topic.VISUALIZATION: parse_visualization,
}


def read(topic: str, payload: bytes, directory: RobotDirectory, arrived: Counter[str]) -> Received:
    """The message on `topic`, of a known robot, whole and about that robot; else Dropped saying why.
    Counts it in `arrived` (topic -> messages of known robots) once it is known to be the robot's."""
    try:
        identity, kind = parse_topic(topic)
    except ProtocolError as exc:
        raise Dropped(Drop.TOPIC, str(exc)) from None
    if kind not in PARSERS:
        raise Dropped(Drop.TOPIC, f"the bridge does not read {kind.value!r} messages")
    name = directory.name(identity)
    if name is None:
        raise Dropped(Drop.UNKNOWN_ROBOT, "no robot has these topic levels")
    # A robot whose version no operator chose is found on every major version's topics (RobotDirectory);
    # a message on another major version's topic than the one it speaks is its own only if its header
    # names a version of that major (which it then speaks: `Bridge._learn_version`).
    speaks = directory.versions[name][0]
    elsewhere = major_version_of(speaks) != identity.major_version
    if not elsewhere:
        arrived[kind.value] += 1
    if len(payload) > settings.MQTT_MAX_PAYLOAD_BYTES:
        raise Dropped(Drop.TOO_LARGE, f"{len(payload)} bytes, over {settings.MQTT_MAX_PAYLOAD_BYTES}")
    try:
        message = PARSERS[kind](payload)
        order = _order(message)
    except PayloadError as exc:
        raise Dropped(Drop(exc.problem.value), str(exc)) from None
    except ProtocolError as exc:
        raise Dropped(Drop.SCHEMA, str(exc)) from None
    if elsewhere:
        said = supported_version(message.version) if message.version is not None else None
        if said is None or major_version_of(said) != identity.major_version:
            raise Dropped(
                Drop.UNKNOWN_ROBOT,
                f"robot {name} speaks {speaks}, this message on a {identity.major_version}"
                f" topic says {message.version!r}",
            )
        arrived[kind.value] += 1
    if order is not None and order[0] > (time.time() + tuning.FUTURE_TOLERANCE_SECONDS) * 1000:
        raise Dropped(Drop.FUTURE, f"timestamp {message.timestamp} is ahead of this host's clock")
    if NUL_ESCAPE in payload and holds_nul(orjson.loads(payload)):
        raise Dropped(Drop.NUL, "a string holds a NUL character")
    for field_name, value, expected in (
        ("manufacturer", message.manufacturer, identity.manufacturer),
        ("serialNumber", message.serial_number, identity.serial_number),
    ):
        if value is not None and value != expected:
            raise Dropped(Drop.HEADER_MISMATCH, f"header {field_name} {value!r} on {expected!r}'s topic")
    if isinstance(message, Connection) and message.connection_state == ConnectionState.ONLINE:
        return Received(name, kind, message, payload, None)  # changes nothing: see `_order`
    digest = state_digest(message) if isinstance(message, State) else None
    return Received(name, kind, message, payload, order, digest, identity.major_version)


class DropLog:
    """Logs dropped and ignored messages at most once per tuning.DROP_LOG_SECONDS per topic and reason,
    saying how many it left out: a robot (or anyone) flooding the broker with junk must not flood the logs
    too."""

    def __init__(self) -> None:
        self._logged_at: dict[tuple[str, str], float] = {}
        self._left_out: Counter[tuple[str, str]] = Counter()

    def log(self, level: int, topic_label: str, reason: str, topic: str, detail: str) -> None:
        key = (topic_label, reason)
        now = time.monotonic()
        if now - self._logged_at.get(key, float("-inf")) < tuning.DROP_LOG_SECONDS:
            self._left_out[key] += 1
            return
        self._logged_at[key] = now
        left_out = self._left_out.pop(key, 0)
        more = f" ({left_out} more since the last such line)" if left_out else ""
        verb = "dropped" if level >= logging.WARNING else "ignored"
        logger.log(level, "%s message on %.200s (%s): %.300s%s", verb, topic, reason, detail, more)


def topic_label_of(topic: str) -> str:
    """The `topic` label of a message's counters: its last level if that names a VDA 5050 topic, else
    `other` (labels are few whatever arrives)."""
    last = topic.rsplit("/", 1)[-1]
    return last if last in TOPIC_NAMES else "other"


def holds_nul(data: Any) -> bool:
    """Whether any key or string in the JSON value holds a NUL character (without recursion)."""
    stack = [data]
    while stack:
        value = stack.pop()
        if isinstance(value, str):
            if "\x00" in value:
                return True
        elif isinstance(value, dict):
            stack.extend(value.keys())
            stack.extend(value.values())
        elif isinstance(value, list):
            stack.extend(value)
    return False


def _order(message: State | Connection | Factsheet | Visualization) -> tuple[int, int] | None:
    """The message's (timestamp ms, headerId), by which the robot's messages on its topic are ordered.

    Disconnections are ordered among themselves only: the broker sends a robot's last will (CONNECTIONBROKEN)
    with the header the robot gave it when it connected, older than the ONLINE it sent next. So a replayed
    or older disconnection is ignored, and a robot's real last will still marks it offline."""
    if message.timestamp is None or message.header_id is None:  # a visualization may lack its header
        return None
    return _timestamp_ms(message.timestamp), message.header_id


def _timestamp_ms(timestamp: str) -> int:
    try:
        moment = datetime.fromisoformat(timestamp.replace("Z", "+00:00"))
    except ValueError:
        raise ProtocolError("timestamp", f"{timestamp!r} is not an ISO 8601 timestamp") from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return int(moment.timestamp() * 1000)
