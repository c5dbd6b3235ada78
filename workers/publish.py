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
    pipeline of the step's metrics, which goes to Redis after the messages are out).

    On each topic only the messages before the first one the broker connection dropped count as
    published: the robot's next step sends the rest again, so the robot sees no headerId left out."""
    published: dict[str, int] = {}
    dropped: set[str] = set()
    for message in messages:
        topic = message.topic.value
        if publisher().publish(topic_for(address, message.topic), message.payload):
            metrics.count(metrics.MESSAGES_OUT, pipe=counters, topic=topic)
            if topic not in dropped:
                published[topic] = max(message.header_id, published.get(topic, -1))
        else:
            dropped.add(topic)
    livestate.mark_published(counters, name, published)
