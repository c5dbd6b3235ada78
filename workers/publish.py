"""Publishing what a step decided, encoded and numbered by the step (`missions.robot_step._wire_messages`)."""

import redis

from missions.robot_step import WireMessage
from robots import livestate
from vda5050.topics import RobotAddress, topic_for
from workers import metrics
from workers.mqtt import publisher


def publish(
    *, name: str, address: RobotAddress, messages: list[WireMessage], counters: redis.client.Pipeline
) -> None:
    """Send those of `messages` to robot `name` that no other step sends (`livestate.claim_published`),
    and count them in `counters` (the caller's pipeline of the step's metrics, which goes to Redis after
    the messages are out).

    A message the broker connection dropped gives its claim back, with those after it on its topic: the
    robot's next step sends them again, so the robot sees no headerId left out."""
    claims = livestate.claim_published(name, [(m.topic.value, m.header_id) for m in messages])
    claimed: dict[str, int] = {}  # topic -> the last headerId claimed on it
    dropped: dict[str, int] = {}  # topic -> the first headerId dropped on it
    for message, mine in zip(messages, claims, strict=True):
        if not mine:
            continue
        topic = message.topic.value
        claimed[topic] = message.header_id
        if topic not in dropped and publisher().publish(topic_for(address, message.topic), message.payload):
            metrics.count(metrics.MESSAGES_OUT, pipe=counters, topic=topic)
        else:
            dropped.setdefault(topic, message.header_id)
    for topic, first in dropped.items():
        livestate.unclaim_published(counters, name, topic, claimed[topic], first - 1)
