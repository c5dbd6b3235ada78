"""Publishing what a step decided: header stamped at send time, so resends get fresh headerIds."""

from datetime import UTC, datetime

import redis

from missions.dispatch import Outgoing
from vda5050.codec import encode, header_for
from vda5050.models import OrderContent
from vda5050.topics import RobotAddress, Topic, topic_for
from workers import livestate, metrics
from workers.mqtt import publisher


def publish(
    *,
    robot: str,
    address: RobotAddress,
    instant_actions_key: str,
    messages: list[Outgoing],
    counters: redis.client.Pipeline,
) -> None:
    """Send `messages`. Their headerIds are drawn in the round trip that also runs `counters` (the step's
    metrics, with these messages' counts added), so a step talks to Redis once after its transaction."""
    if not messages:
        counters.execute()
        return
    topics = [Topic.ORDER if isinstance(m.content, OrderContent) else Topic.INSTANT_ACTIONS for m in messages]
    for topic in topics:
        metrics.count(metrics.MESSAGES_OUT, pipe=counters, topic=topic.value)
    header_ids = livestate.next_header_ids(robot, topics, pipe=counters)
    now = datetime.now(UTC)
    for message, topic, header_id in zip(messages, topics, header_ids, strict=True):
        header = header_for(address, header_id=header_id, at=now)
        payload = encode(message.content, header, instant_actions_key=instant_actions_key)
        publisher().publish(topic_for(address, topic), payload)
