"""Publishing what a step decided, encoded and numbered by the step (`missions.services._wire_messages`)."""

import redis

from missions.services import WireMessage
from vda5050.topics import RobotAddress, topic_for
from workers import livestate, metrics
from workers.mqtt import publisher


def publish(
    *, name: str, address: RobotAddress, messages: list[WireMessage], counters: redis.client.Pipeline
) -> None:
    """Send `messages` to robot `name`, and count them and mark them published in `counters` (the caller's
    pipeline of the step's metrics, which goes to Redis after the messages are out)."""
    published: dict[str, int] = {}
    for message in messages:
        publisher().publish(topic_for(address, message.topic), message.payload)
        metrics.count(metrics.MESSAGES_OUT, pipe=counters, topic=message.topic.value)
        published[message.topic.value] = max(message.header_id, published.get(message.topic.value, -1))
    livestate.mark_published(counters, name, published)
