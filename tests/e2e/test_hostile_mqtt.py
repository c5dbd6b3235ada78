"""The hostile corpus (tests/workers/bridge/hostile.py) published through Mosquitto to the real bridge
process: each message is counted under its reason, nothing the bridge stores changes, and the bridge goes
on working."""

import uuid
from collections import Counter
from collections.abc import Iterator
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
from django.conf import settings

from robots import livestate
from robots.models import Robot
from tests.e2e.conftest import Stack
from tests.e2e.helpers import create_robot
from tests.waiting import wait_for
from tests.workers.bridge.hostile import corpus, history
from tests.workers.bridge.messages import state_message, topic
from workers import metrics
from workers.bridge.status_writer import STATUS_COLUMNS

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# What the bridge writes of a robot's row (steps write the rest: header counters, outbox, state).
BRIDGE_COLUMNS = (*STATUS_COLUMNS, "last_state_at", "online", "factsheet", "agv_class", "speed_max")


@pytest.fixture
def publisher() -> Iterator[mqtt.Client]:
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
    client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
    client.loop_start()
    yield client
    client.loop_stop()
    client.disconnect()


def counters() -> Counter[str]:
    raw = livestate.client().hgetall(metrics.COUNTERS)
    return Counter({field.decode(): int(value) for field, value in raw.items()})


def stored(name: str) -> dict[str, Any]:
    """What the bridge stored about the robot: its columns, its live state (without the steps' publishing
    marks), whether and when it was heard."""
    client = livestate.client()
    live = client.hgetall(livestate.robot_key(name))
    return {
        "row": Robot.objects.filter(name=name).values(*BRIDGE_COLUMNS).get(),
        "live": {key: value for key, value in live.items() if not key.startswith(b"published:")},
        "online": client.sismember(livestate.ONLINE_SET, name),
        "last_seen": client.zscore(livestate.LAST_SEEN, name),
    }


def test_hostile_messages_through_the_broker_are_counted_change_nothing_and_the_bridge_goes_on(
    stack: Stack, api, unique, publisher: mqtt.Client
) -> None:
    victim = unique("victim")
    create_robot(api, victim, heartbeat_timeout=600)  # no heartbeat check takes it offline meanwhile
    # The bridge reloads its robots at most every 2 s: until then the robot's messages are unknown_robot's.
    # A visualization without header is not ordered, so this one can be sent until it arrives.
    probe = {"agvPosition": {"x": -1.0, "y": 0.0, "theta": 0.0, "mapId": "map", "positionInitialized": True}}

    def known() -> bool:
        publisher.publish(topic(victim, "visualization"), orjson.dumps(probe), qos=1).wait_for_publish()
        return Robot.objects.filter(name=victim, pose_x=-1.0).exists()

    wait_for(known, message="the bridge knows the robot")
    for topic_name, payload in history(victim):
        publisher.publish(topic_name, payload, qos=1).wait_for_publish()
    wait_for(
        lambda: Robot.objects.filter(name=victim, online=True, pose_x=7.0, factsheet__isnull=False).exists(),
        message="the robot's history stored",
    )
    before, counters_before = stored(victim), counters()
    stranger = f"stranger-{uuid.uuid4().hex[:8]}"
    cases = [case for case in corpus(victim, stranger) if case.via_broker]
    expected = Counter(f"{case.counter}|reason={case.reason}|topic={case.label}" for case in cases)

    for case in cases:
        publisher.publish(case.topic, case.payload, qos=1).wait_for_publish()

    def counted() -> Counter[str]:
        return counters() - counters_before

    wait_for(lambda: counted() >= expected, message="every case counted")
    # Each case once; robots of other tests and programs on the same broker may add unknown_robot counts.
    exact = {field: n for field, n in expected.items() if "reason=unknown_robot" not in field}
    assert {field: counted()[field] for field in exact} == exact
    assert stack.processes["bridge"].running()
    assert stored(victim) == before
    assert not Robot.objects.filter(serial_number=stranger).exists()
    text = api.get("/metrics").content.decode()
    assert 'fleet_messages_invalid_total{reason="too_deep",topic="factsheet"}' in text
    assert 'fleet_messages_ignored_total{reason="replayed",topic="connection"}' in text

    publisher.publish(*state_message(victim, header_id=2, at=20.0, battery=44.0), qos=1).wait_for_publish()

    wait_for(lambda: Robot.objects.get(name=victim).battery_level == 44.0, message="a good state afterwards")
    assert stack.processes["bridge"].running()
