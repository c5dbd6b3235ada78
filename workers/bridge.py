"""The MQTT bridge: robots' messages in, live state to Redis, coalesced status to PostgreSQL, steps woken.

Per state message it costs one parse and one pipelined Redis script call; the database sees one batched
UPDATE per flush period for the robots whose status changed, and a step runs only when something the
engine cares about changed (`dispatch.held.state_digest`). A robot that only took the order its last
step sent needs no step either (`dispatch.held.takes_order_only`): the flush marks the order accepted,
so that the sweep does not send it again. The bridge runs no step itself: it queues them for the Celery
step workers (`workers.steps.request_steps`), one request per batch of states. Several bridges may run at
once with an MQTT shared subscription (`FLEET_BRIDGE_SHARE_GROUP`): the Redis script orders each
robot's states by the robot's own timestamp and headerId, so it does not matter which bridge sees what.
A message it cannot take is dropped and counted by reason (`Drop`), one older than the robot's last on its
topic is ignored and counted (`Ignored`); either way the rest of the batch goes on (README, Metrics).
"""

import logging
import queue
import threading
import time
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

import orjson
import paho.mqtt.client as mqtt
from django.conf import settings
from django.db import DatabaseError, connections

from dispatch.held import StateDigest, state_digest, takes_order_only
from kit.db import drop_broken_connections, jsonb
from missions.selectors import robots_with_missions
from missions.services import mission_orders_accepted
from robots import livestate
from robots.choices import AgvClass, SettingSource
from robots.models import Robot
from robots.status import robot_protocol_version_learn, robot_status_write, robots_came_online
from vda5050.codec import nested_deeper, parse_connection, parse_factsheet, parse_state, parse_visualization
from vda5050.errors import PayloadError, ProtocolError
from vda5050.maps import reported_maps
from vda5050.models import Connection, ConnectionState, Factsheet, State, Visualization
from vda5050.topics import RobotIdentity, Topic, fleet_subscription, major_version_of, parse_topic
from vda5050.topics import shared_subscription as shared_filter
from vda5050.versions import SUPPORTED_VERSIONS, supported_version
from workers import metrics
from workers.mqtt import new_client
from workers.stepper import keep_trying, settle_long_lived_process
from workers.steps import request_steps

logger = logging.getLogger(__name__)

SUBSCRIBED_TOPICS = (Topic.STATE, Topic.CONNECTION, Topic.FACTSHEET, Topic.VISUALIZATION)
SPOKEN_MAJORS = frozenset(major_version_of(version) for version in SUPPORTED_VERSIONS)
# Messages handled per pipeline round trip. A batch's steps are requested once all of it is handled, so a
# backlog (the bridge starved of CPU for a moment) is worked off in small batches: with 2,000, a state
# that needs a step waited behind hundreds of periodic ones (bench/README.md, "What changed": N=2000).
BATCH_LIMIT = 100
# A batch also takes what arrives this long after its first message. A batch's Redis round trip costs the
# processing thread several times a state's own work, and without the window a busy fleet's batches held
# only a few states: a state now waits up to the window more, and the machine has that CPU for the steps
# (bench/README.md, "What changed").
BATCH_WINDOW_SECONDS = 0.002
DIRECTORY_REFRESH_SECONDS = 2.0  # an unknown robot triggers at most one directory reload this often
LAST_STATE_AT_PERIOD = 10.0  # seconds between last_state_at writes of a robot whose status is unchanged
FORGET_STATUS_SECONDS = 60.0  # a robot silent this long is forgotten until it is heard again
FAILURE_PAUSE_SECONDS = 1.0  # after an iteration failed (database or Redis unreachable)
# A message timestamped further ahead of this host's clock is dropped: stored, it would make every message
# the robot sends until then look older, and be ignored (a robot whose clock is this far off needs fixing).
FUTURE_TOLERANCE_SECONDS = 300.0
DROP_LOG_SECONDS = 10.0  # one log line per topic and reason this often, however many messages are dropped
TOPIC_NAMES = frozenset(topic.value for topic in Topic)
NUL_ESCAPE = b"\\u0000"  # how JSON writes a NUL character, which PostgreSQL stores in neither text nor jsonb
STATUS_COLUMNS = (
    "battery_level",
    "pose_x",
    "pose_y",
    "pose_theta",
    "pose_map_id",
    "position_initialized",
    "hardware_version",
    "errors",
    "info_messages",
    "maps",
)
JSON_COLUMNS = frozenset({"hardware_version", "errors", "info_messages", "maps"})


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
    FUTURE = "future"  # timestamped more than FUTURE_TOLERANCE_SECONDS ahead of this host's clock
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


class DropLog:
    """Logs dropped and ignored messages at most once per DROP_LOG_SECONDS per topic and reason, saying how
    many it left out: a robot (or anyone) flooding the broker with junk must not flood the logs too."""

    def __init__(self) -> None:
        self._logged_at: dict[tuple[str, str], float] = {}
        self._left_out: Counter[tuple[str, str]] = Counter()

    def log(self, level: int, topic_label: str, reason: str, topic: str, detail: str) -> None:
        key = (topic_label, reason)
        now = time.monotonic()
        if now - self._logged_at.get(key, float("-inf")) < DROP_LOG_SECONDS:
            self._left_out[key] += 1
            return
        self._logged_at[key] = now
        left_out = self._left_out.pop(key, 0)
        more = f" ({left_out} more since the last such line)" if left_out else ""
        verb = "dropped" if level >= logging.WARNING else "ignored"
        logger.log(level, "%s message on %.200s (%s): %.300s%s", verb, topic, reason, detail, more)


@dataclass
class RobotStatus:
    """A robot's status as last written to PostgreSQL, and what is waiting to be written."""

    last_state_at_period: float  # s between writes of an unchanged status's newer last_state_at
    heard_at: float  # monotonic s of the robot's last message
    written: dict[str, Any] = field(default_factory=dict)
    pending: dict[str, Any] = field(default_factory=dict)
    written_at: float = 0.0
    last_state_at: datetime | None = None
    last_state_at_written: datetime | None = None


@dataclass
class Flush:
    """One status write: robot -> (orderId, orderUpdateId) it took, and columns -> rows of values + name."""

    orders: dict[str, tuple[str, int]]
    statuses: dict[tuple[str, ...], list[tuple[Any, ...]]] = field(default_factory=dict)


class RobotDirectory:
    """Which robot a topic belongs to: (interface, major version, manufacturer, serial number) -> name.

    A robot whose version no operator chose is found on every major version we speak: the version it
    speaks is learned from its messages (`Bridge._learn_version`)."""

    def __init__(self) -> None:
        self._names: dict[RobotIdentity, str] = {}
        self.versions: dict[str, tuple[str, bool]] = {}  # name -> (version we speak, chosen by an operator)
        self._loaded_at = float("-inf")

    def name(self, identity: RobotIdentity) -> str | None:
        name = self._names.get(identity)
        if name is None and time.monotonic() - self._loaded_at > DIRECTORY_REFRESH_SECONDS:
            self.reload()
            name = self._names.get(identity)
        return name

    def reload(self) -> None:
        rows = Robot.objects.values_list(
            "name",
            "interface_name",
            "manufacturer",
            "serial_number",
            "protocol_version",
            "protocol_version_source",
        )
        self._names = {}
        self.versions = {}
        for name, interface, manufacturer, serial, version, source in rows:
            by_operator = source == SettingSource.OPERATOR
            majors = {major_version_of(version)} if by_operator else SPOKEN_MAJORS
            for major in majors:
                self._names[RobotIdentity(interface, major, manufacturer, serial)] = name
            self.versions[name] = (version, by_operator)
        self._loaded_at = time.monotonic()


class Bridge:
    def __init__(self, share_group: str = "") -> None:
        self.share_group = share_group
        self.inbox: queue.SimpleQueue[tuple[str, bytes, float]] = (
            queue.SimpleQueue()
        )  # topic, payload, arrival
        self.directory = RobotDirectory()
        self.status: dict[str, RobotStatus] = {}
        self.accepted_orders: dict[str, tuple[str, int]] = {}  # robot -> (orderId, orderUpdateId) it took
        self.client = new_client("bridge")
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self._last_flush = time.monotonic()
        self._writes: queue.SimpleQueue[Flush | None] = queue.SimpleQueue()  # to the writer; None: end
        self._writer: threading.Thread | None = None
        self._written = threading.Event()  # no flush is being written
        self._written.set()
        self._skipped: queue.SimpleQueue[str] = queue.SimpleQueue()  # robots whose status a write skipped
        self._drop_log = DropLog()

    # --- MQTT thread ---

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        """(Re)subscribe on every connect: a broker restart loses non-persistent sessions."""
        if reason.is_failure:
            logger.warning("bridge could not connect to MQTT broker: %s", reason)
            return
        filters = [
            shared_filter(self.share_group, topic) if self.share_group else fleet_subscription(topic)
            for topic in SUBSCRIBED_TOPICS
        ]
        client.subscribe([(topic_filter, 0) for topic_filter in filters])
        logger.info("bridge connected, subscribed to %s", filters)

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        self.inbox.put((message.topic, message.payload, time.time()))

    # --- processing thread ---

    def run_forever(self) -> None:
        keep_trying("loading the robots", self._resume)
        settle_long_lived_process()
        self.start_status_writer()
        self.client.connect_async(settings.MQTT_HOST, settings.MQTT_PORT, keepalive=30)
        self.client.loop_start()
        try:
            while True:
                try:
                    self.run_once(timeout=settings.BRIDGE_STATUS_FLUSH_SECONDS)
                except Exception:  # PostgreSQL or Redis away for a moment: the bridge waits, never exits
                    logger.exception("bridge iteration failed; going on in %s s", FAILURE_PAUSE_SECONDS)
                    time.sleep(FAILURE_PAUSE_SECONDS)
        finally:
            self.client.loop_stop()
            self.stop_status_writer()

    def _resume(self) -> None:
        self.directory.reload()
        # A state stored just before this bridge last stopped may have lost its step: step every robot with
        # work once (a step that finds nothing to do costs only its reads).
        request_steps(robots_with_missions())

    def run_once(self, timeout: float) -> None:
        """Handle whatever arrived (waiting up to `timeout` for something, then up to BATCH_WINDOW_SECONDS
        for more); when a flush is due and the last one is written, hand the next to the status-writer
        thread (`start_status_writer`, which `run_forever` starts; without it flushes wait here)."""
        batch = self._drain(timeout)
        drop_broken_connections()
        if batch:
            self.handle([(topic, payload) for topic, payload, _ in batch], received_at=batch[0][2])
        due = time.monotonic() - self._last_flush >= settings.BRIDGE_STATUS_FLUSH_SECONDS
        if due and self._written.is_set():
            self._written.clear()
            self._writes.put(self._collect())

    def _drain(self, timeout: float) -> list[tuple[str, bytes, float]]:
        try:
            batch = [self.inbox.get(timeout=timeout)]
        except queue.Empty:
            return []
        self._take_queued(batch)
        if len(batch) < BATCH_LIMIT:
            # One sleep, not a wait per message, which would wake this thread for every message the window
            # gathers. Arrival times are wall-clock: bounded, so a clock stepped back cannot stall the bridge.
            window_left = batch[0][2] + BATCH_WINDOW_SECONDS - time.time()
            time.sleep(min(BATCH_WINDOW_SECONDS, max(0.0, window_left)))
            self._take_queued(batch)
        return batch

    def _take_queued(self, batch: list[tuple[str, bytes, float]]) -> None:
        while len(batch) < BATCH_LIMIT:
            try:
                batch.append(self.inbox.get_nowait())
            except queue.Empty:
                return

    def handle(self, batch: list[tuple[str, bytes]], received_at: float | None = None) -> None:
        """Read a batch, store states (and order the other topics' messages) in one Redis pipeline, then act
        on what is new. A message that cannot be read is dropped, one older than what is known is ignored;
        either is counted (`messages_invalid`, `messages_ignored`) and the rest of the batch goes on.

        `received_at` (epoch s) is when the batch's first message arrived: step latency counts from there,
        and it stands for every state's arrival (the earliest, so a resend never comes early).
        """
        arrived_at = received_at or time.time()
        # One round trip: the store_state and order_message calls first (their results lead), then counters.
        pipe = livestate.client().pipeline(transaction=False)
        queued: list[Received] = []  # in the order of their store_state/order_message calls on `pipe`
        arrived: Counter[str] = Counter()  # topic -> messages of known robots
        invalid: Counter[tuple[str, str]] = Counter()  # (topic, reason) -> messages dropped
        for topic, payload in batch:
            if not payload:
                continue  # clearing a retained message (connection, factsheet) is not a message
            try:
                received = self._read(topic, payload, arrived)
            except Dropped as dropped:
                label = _topic_label(topic)
                invalid[label, dropped.reason] += 1
                self._drop_log.log(logging.WARNING, label, dropped.reason, topic, str(dropped))
                continue
            if received.kind == Topic.STATE:
                assert received.order is not None and received.digest is not None
                livestate.store_state(
                    pipe,
                    name=received.name,
                    payload=payload,
                    timestamp_ms=received.order[0],
                    header_id=received.order[1],
                    digest=received.digest,
                    arrived_at=arrived_at,
                )
            elif received.order is not None:
                timestamp_ms, header_id = received.order
                livestate.order_message(
                    pipe,
                    name=received.name,
                    topic=received.kind,
                    timestamp_ms=timestamp_ms,
                    header_id=header_id,
                )
            else:  # an ONLINE connection changes nothing; a visualization without header is not ordered
                if received.kind == Topic.VISUALIZATION:
                    self._visualization(received)
                continue
            queued.append(received)
        for topic_label, by in arrived.items():
            metrics.count(metrics.MESSAGES_IN, by=by, pipe=pipe, topic=topic_label)
        for (topic_label, reason), by in invalid.items():
            metrics.count(metrics.MESSAGES_INVALID, by=by, pipe=pipe, topic=topic_label, reason=reason)
        results = livestate.execute(pipe)
        changed: set[str] = set()
        came_online: list[str] = []
        disconnected: set[str] = set()  # a later state in the same batch reconnects
        late: Counter[tuple[str, str, str]] = Counter()  # (counter, topic, reason) -> messages
        for received, result in zip(queued, results[: len(queued)], strict=True):
            outcome = livestate.stored(result) if received.kind == Topic.STATE else None
            code = outcome.outcome if outcome is not None else result
            if code in (livestate.REPLAYED, livestate.STALE):
                reason = Ignored.REPLAYED if code == livestate.REPLAYED else Ignored.STALE
                late[metrics.MESSAGES_IGNORED, received.kind.value, reason] += 1
                where = f"robot {received.name}'s {received.kind}"
                self._drop_log.log(logging.INFO, received.kind, reason, where, "not newer than the last")
            elif received.kind == Topic.STATE:
                assert outcome is not None
                self._stored_state(received, outcome, changed)
                disconnected.discard(received.name)
                if outcome.came_online:
                    came_online.append(received.name)
            elif received.kind == Topic.CONNECTION:
                disconnected.add(received.name)  # only disconnections are ordered (`_read`)
            elif received.kind == Topic.VISUALIZATION:
                self._visualization(received)
            elif received.kind == Topic.FACTSHEET:
                try:
                    self._store_factsheet(received)
                except DatabaseError as exc:
                    late[metrics.MESSAGES_INVALID, received.kind.value, Drop.REFUSED] += 1
                    where = f"robot {received.name}'s {received.kind}"
                    self._drop_log.log(logging.WARNING, received.kind, Drop.REFUSED, where, str(exc))
            if code not in (livestate.REPLAYED, livestate.STALE) and self._learn_version(received):
                changed.add(received.name)  # what waits for the robot goes out again, in its version
        if late:
            counters = livestate.client().pipeline(transaction=False)
            for (counter, topic_label, reason), by in late.items():
                metrics.count(counter, by=by, pipe=counters, topic=topic_label, reason=reason)
            livestate.execute(counters)
        self._act(changed, came_online, disconnected, received_at=arrived_at)

    def _read(self, topic: str, payload: bytes, arrived: Counter[str]) -> Received:
        """The message on `topic`, of a known robot, whole and about that robot; else Dropped saying why."""
        try:
            identity, kind = parse_topic(topic)
        except ProtocolError as exc:
            raise Dropped(Drop.TOPIC, str(exc)) from None
        if kind not in PARSERS:
            raise Dropped(Drop.TOPIC, f"the bridge does not read {kind.value!r} messages")
        name = self.directory.name(identity)
        if name is None:
            raise Dropped(Drop.UNKNOWN_ROBOT, "no robot has these topic levels")
        # A robot whose version no operator chose is found on every major version's topics (RobotDirectory);
        # a message on another major version's topic than the one it speaks is its own only if its header
        # names a version of that major (which it then speaks: `_learn_version`).
        speaks = self.directory.versions[name][0]
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
        if order is not None and order[0] > (time.time() + FUTURE_TOLERANCE_SECONDS) * 1000:
            raise Dropped(Drop.FUTURE, f"timestamp {message.timestamp} is ahead of this host's clock")
        if NUL_ESCAPE in payload and _holds_nul(orjson.loads(payload)):
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

    def _stored_state(self, received: Received, store: livestate.Stored, changed: set[str]) -> None:
        state = received.message
        assert isinstance(state, State)
        self._remember_status(received.name, state)
        if store.outcome != livestate.CHANGED:
            return
        digest = received.digest
        assert digest is not None
        if store.replaced is not None and takes_order_only(store.replaced, digest):
            self.accepted_orders[received.name] = (digest.order_id, digest.order_update_id)
        else:
            changed.add(received.name)

    def _visualization(self, received: Received) -> None:
        visualization = received.message
        assert isinstance(visualization, Visualization)
        position = visualization.agv_position
        if position is not None:
            self._pending(received.name).update(
                pose_x=position.x, pose_y=position.y, pose_theta=position.theta
            )

    def _act(
        self, changed: set[str], came_online: list[str], disconnected: set[str], *, received_at: float
    ) -> None:
        # The steps are requested whatever fails here: with PostgreSQL away they fail too, and are retried
        # until it is back; a lost request would leave the robot unstepped until its state changes again.
        try:
            if came_online:
                try:
                    robots_came_online(names=came_online)
                except DatabaseError:
                    livestate.client().srem(
                        livestate.ONLINE_SET, *came_online
                    )  # their next state tries again
                    raise
            for name in disconnected:
                if livestate.mark_offline(name):
                    Robot.objects.filter(name=name).update(online=False)
                    changed.add(name)
        finally:
            request_steps(changed | set(came_online) | disconnected, at=received_at)

    def _status(self, name: str) -> RobotStatus:
        """The robot's status, now heard from."""
        status = self.status.get(name)
        if status is None:
            # A period of its own, from 1/2 to 1 LAST_STATE_AT_PERIOD: robots that came online together (a
            # fleet starting) would otherwise rewrite their unchanged statuses together for ever after.
            spread = 0.5 + (zlib.crc32(name.encode()) % 1024) / 2048
            status = self.status[name] = RobotStatus(LAST_STATE_AT_PERIOD * spread, time.monotonic())
        else:
            status.heard_at = time.monotonic()
        return status

    def _remember_status(self, name: str, state: State) -> None:
        status = self._status(name)
        position = state.agv_position
        values: dict[str, Any] = {
            "battery_level": state.battery_state.battery_charge,
            "hardware_version": {"manufacturer": state.manufacturer, "serial_number": state.serial_number},
            "errors": {
                error.error_type: {
                    "level": error.error_level.value,
                    "description": error.error_description,
                    "references": {r.reference_key: r.reference_value for r in error.error_references or ()},
                }
                for error in state.errors
            },
            "info_messages": _user_info(state),
            "maps": reported_maps(state),
        }
        if position is not None:
            values.update(
                pose_x=position.x,
                pose_y=position.y,
                pose_theta=position.theta,
                pose_map_id=position.map_id,
                position_initialized=position.position_initialized,
            )
        status.pending.update(values)
        status.last_state_at = datetime.now(UTC)

    def _pending(self, name: str) -> dict[str, Any]:
        return self._status(name).pending

    def _learn_version(self, received: Received) -> bool:
        """Speak to the robot the version its message says (the newest we speak of its major version, see
        `vda5050.versions.supported_version`), unless an operator chose one; True if that changed it. The
        topic's major version is the robot's word too: a version the header names on another major's topic
        is not learned. A write PostgreSQL refuses is tried again with the robot's next message."""
        current, by_operator = self.directory.versions.get(received.name, (None, True))
        said = received.message.version
        version = supported_version(said) if said is not None else None
        if by_operator or version in (None, current) or major_version_of(version) != received.major_version:
            return False
        try:
            if not robot_protocol_version_learn(name=received.name, version=version):
                return False
        except DatabaseError:
            logger.exception("robot %s: version %s not stored", received.name, version)
            return False
        logger.info(
            "robot %s speaks VDA 5050 %s (its %s says %s)", received.name, version, received.kind, said
        )
        self.directory.reload()
        return True

    def _store_factsheet(self, received: Received) -> None:
        factsheet = received.message
        assert isinstance(factsheet, Factsheet)
        agv_class = str(factsheet.type_specification.agv_class)
        Robot.objects.filter(name=received.name).update(
            factsheet=orjson.loads(received.payload),
            agv_class=agv_class if agv_class in AgvClass.values else AgvClass.CARRIER,
            speed_max=factsheet.physical_parameters.speed_max,
        )

    def flush(self) -> None:
        """Write the orders robots took and the robots' changed statuses now, in this thread."""
        self._write(self._collect())

    def start_status_writer(self) -> None:
        """The thread that writes the flushes `run_once` collects, so that the processing thread goes on
        handling states while a flush waits for PostgreSQL (it stopped them for every write)."""
        self._writer = threading.Thread(target=self._write_forever, name="status-writer", daemon=True)
        self._writer.start()

    def stop_status_writer(self) -> None:
        """Let the status writer write what it holds, and end with its database connection closed."""
        if self._writer is not None:
            self._writes.put(None)
            self._writer.join(timeout=30)
            self._writer = None

    def _write_forever(self) -> None:
        while (flush := self._writes.get()) is not None:
            try:
                drop_broken_connections()
                self._write(flush)
            except Exception:  # PostgreSQL away for a moment: statuses are rewritten once they change
                logger.exception("status flush failed")
            finally:
                self._written.set()
        connections.close_all()  # this thread's

    def _collect(self) -> Flush:
        """Take what the next write holds: the orders robots took, and each robot's status that changed or
        whose newer last_state_at is due; unchanged robots cost nothing, and robots long silent are
        forgotten (a deleted one would stay for ever)."""
        self._restore_skipped()
        now = time.monotonic()
        flush = Flush(orders=self.accepted_orders)
        self.accepted_orders = {}
        silent = []
        for name, status in self.status.items():
            changed = {
                key: value for key, value in status.pending.items() if status.written.get(key) != value
            }
            due = (
                status.last_state_at != status.last_state_at_written
                and now - status.written_at >= status.last_state_at_period
            )
            if not changed and not due:
                if now - status.heard_at >= FORGET_STATUS_SECONDS:
                    silent.append(name)
                continue
            status.written.update(status.pending)
            status.pending = {}
            status.written_at = now
            status.last_state_at_written = status.last_state_at
            columns = tuple(column for column in STATUS_COLUMNS if column in status.written)
            values = [jsonb(status.written[c]) if c in JSON_COLUMNS else status.written[c] for c in columns]
            if status.last_state_at is not None:  # a robot only seen on visualization keeps its time
                columns += ("last_state_at",)
                values.append(status.last_state_at)
            flush.statuses.setdefault(columns, []).append((*values, name))
        for name in silent:
            del self.status[name]
        self._last_flush = now
        return flush

    def _write(self, flush: Flush) -> None:
        """Each group of statuses in one statement; robots a step holds are skipped and rewritten in full by
        the next flush (`_restore_skipped`)."""
        if flush.orders:
            try:
                mission_orders_accepted(orders=flush.orders)
            except DatabaseError:  # harmless: the sweep's step finds the order taken instead of resending it
                logger.exception("acceptance of %d orders not written", len(flush.orders))
        for columns, rows in flush.statuses.items():
            try:
                skipped = robot_status_write(columns=columns, rows=rows)
            except DatabaseError:
                # One robot's value the database refuses (a NUL in an error text, say) must not hold back
                # the others': row by row, dropping what fails (rewritten once it changes).
                logger.warning("status flush of %d robots failed; writing them one by one", len(rows))
                skipped = set()
                for row in rows:
                    try:
                        skipped |= robot_status_write(columns=columns, rows=[row])
                    except DatabaseError:
                        logger.exception("status of robot %s not written", row[-1])
                        metrics.count(metrics.STATUS_WRITES_FAILED)
            for name in skipped:
                self._skipped.put(name)

    def _restore_skipped(self) -> None:
        """What the last write skipped is pending again, under what changed since."""
        while True:
            try:
                name = self._skipped.get_nowait()
            except queue.Empty:
                return
            status = self.status.get(name)
            if status is not None:
                status.pending = {**status.written, **status.pending}
                status.written, status.written_at, status.last_state_at_written = {}, 0.0, None


def _topic_label(topic: str) -> str:
    """The `topic` label of a message's counters: its last level if that names a VDA 5050 topic, else
    `other` (labels are few whatever arrives)."""
    last = topic.rsplit("/", 1)[-1]
    return last if last in TOPIC_NAMES else "other"


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


def _holds_nul(data: Any) -> bool:
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


def _user_info(state: State) -> Any:
    """The reference's `info_messages`: the JSON of the robot's `user_info` information entry; its text if
    that is no JSON PostgreSQL can store and the flush can serialize (NUL, nested too deep)."""
    for info in state.information or ():
        if info.info_type == "user_info" and info.info_description:
            try:
                value = orjson.loads(info.info_description)
            except orjson.JSONDecodeError:
                return info.info_description
            return info.info_description if nested_deeper(value) or _holds_nul(value) else value
    return None
