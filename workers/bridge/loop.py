"""The bridge's batch loop (`Bridge`): the MQTT thread puts what arrives in an inbox; the processing thread
takes it a batch at a time, stores states (and orders the other topics' messages) in one Redis pipeline,
acts on what is new and requests the steps it calls for, once per batch."""

import logging
import queue
import time
from collections import Counter
from typing import Any

import orjson
import paho.mqtt.client as mqtt
from django.conf import settings
from django.db import DatabaseError

from dispatch.held import takes_order_only
from kit.db import drop_broken_connections
from missions.selectors import robots_with_missions
from robots import livestate
from robots.choices import AgvClass
from robots.models import Robot
from robots.status import robot_protocol_version_learn, robots_came_online
from vda5050.models import Factsheet, State, Visualization
from vda5050.topics import Topic, fleet_subscription, major_version_of
from vda5050.topics import shared_subscription as shared_filter
from vda5050.versions import supported_version
from vda5050.zones import supported_zones
from workers import metrics, tuning
from workers.bridge.directory import RobotDirectory
from workers.bridge.gate import Drop, DropLog, Dropped, Ignored, Received, read, topic_label_of
from workers.bridge.status_writer import StatusWriter
from workers.long_lived import keep_trying, settle_long_lived_process
from workers.mqtt import new_client
from workers.step_requests import HeldSteps, queue_steps

logger = logging.getLogger(__name__)

SUBSCRIBED_TOPICS = (Topic.STATE, Topic.CONNECTION, Topic.FACTSHEET, Topic.VISUALIZATION)


class Bridge:
    def __init__(self, share_group: str = "") -> None:
        self.share_group = share_group
        self.inbox: queue.SimpleQueue[tuple[str, bytes, float]] = (
            queue.SimpleQueue()
        )  # topic, payload, arrival
        self.directory = RobotDirectory()
        self.status_writer = StatusWriter()
        self.steps = HeldSteps()
        self.client = new_client("bridge")
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
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
        self.status_writer.start()
        self.client.connect_async(settings.MQTT_HOST, settings.MQTT_PORT, keepalive=30)
        self.client.loop_start()
        try:
            while True:
                try:
                    self.run_once(timeout=settings.BRIDGE_STATUS_FLUSH_SECONDS)
                except Exception:  # PostgreSQL or Redis away for a moment: the bridge waits, never exits
                    logger.exception(
                        "bridge iteration failed; going on in %s s", tuning.FAILURE_PAUSE_SECONDS
                    )
                    time.sleep(tuning.FAILURE_PAUSE_SECONDS)
        finally:
            self.client.loop_stop()
            self.status_writer.stop()

    def _resume(self) -> None:
        self.directory.reload()
        # A state stored just before this bridge last stopped may have lost its step: step every robot with
        # work once (a step that finds nothing to do costs only its reads).
        queue_steps(robots_with_missions())

    def run_once(self, timeout: float) -> None:
        """Handle whatever arrived (waiting up to `timeout` for something, or until held step requests are
        due, then up to tuning.BATCH_WINDOW_SECONDS for more); then send the held step requests and hand
        the status writer its flush if either is due."""
        batch = self._drain(self.steps.wait_seconds(timeout))
        drop_broken_connections()
        if batch:
            self.handle([(topic, payload) for topic, payload, _ in batch], received_at=batch[0][2])
        self.steps.send_if_due()
        self.status_writer.hand_off_if_due()

    def _drain(self, timeout: float) -> list[tuple[str, bytes, float]]:
        try:
            batch = [self.inbox.get(timeout=timeout)]
        except queue.Empty:
            return []
        self._take_queued(batch)
        if len(batch) < tuning.BATCH_LIMIT:
            # One sleep, not a wait per message, which would wake this thread for every message the window
            # gathers. Arrival times are wall-clock: bounded, so a clock stepped back cannot stall the bridge.
            window = tuning.BATCH_WINDOW_SECONDS
            time.sleep(min(window, max(0.0, batch[0][2] + window - time.time())))
            self._take_queued(batch)
        return batch

    def _take_queued(self, batch: list[tuple[str, bytes, float]]) -> None:
        limit = tuning.BATCH_LIMIT
        while len(batch) < limit:
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
                received = read(topic, payload, self.directory, arrived)
            except Dropped as dropped:
                label = topic_label_of(topic)
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

    def _stored_state(self, received: Received, store: livestate.Stored, changed: set[str]) -> None:
        state = received.message
        assert isinstance(state, State)
        self.status_writer.remember_state(received.name, state)
        if store.outcome != livestate.CHANGED:
            return
        digest = received.digest
        assert digest is not None
        if store.replaced is not None and takes_order_only(store.replaced, digest):
            self.status_writer.remember_order_taken(received.name, (digest.order_id, digest.order_update_id))
        else:
            changed.add(received.name)

    def _visualization(self, received: Received) -> None:
        visualization = received.message
        assert isinstance(visualization, Visualization)
        position = visualization.agv_position
        if position is not None:
            self.status_writer.pending(received.name).update(
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
            self.steps.request(changed | set(came_online) | disconnected, at=received_at)

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
        as_sent = orjson.loads(received.payload)
        Robot.objects.filter(name=received.name).update(
            factsheet=as_sent,
            agv_class=agv_class if agv_class in AgvClass.values else AgvClass.CARRIER,
            speed_max=factsheet.physical_parameters.speed_max,
            supported_zones=supported_zones(as_sent),
        )
