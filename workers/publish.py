"""Publishing what a step decided: header stamped at send time, with the headerIds the step drew."""

from datetime import UTC, datetime

import redis

from missions.dispatch import Outgoing
from vda5050.codec import encode, header_for
from vda5050.topics import RobotAddress, topic_for
from workers import metrics
from workers.mqtt import publisher


def publish(
    *,
    address: RobotAddress,
    instant_actions_key: str,
    messages: list[Outgoing],
    header_ids: list[int],
    counters: redis.client.Pipeline,
) -> None:
    """Send `messages` with their `header_ids`, and count them in `counters` (the caller's pipeline of
    the step's metrics, which goes to Redis after the messages are out)."""
    now = datetime.now(UTC)
    for message, header_id in zip(messages, header_ids, strict=True):
        header = header_for(address, header_id=header_id, at=now)
        payload = encode(message.content, header, instant_actions_key=instant_actions_key)
        publisher().publish(topic_for(address, message.topic), payload)
        metrics.count(metrics.MESSAGES_OUT, pipe=counters, topic=message.topic.value)
