"""Publishing what a step decided: header stamped at send time, so resends get fresh headerIds."""

from datetime import UTC, datetime

from missions.dispatch import Outgoing
from vda5050.codec import encode, header_for
from vda5050.models import OrderContent
from vda5050.topics import RobotAddress, Topic, topic_for
from workers import livestate, metrics
from workers.mqtt import publisher


def publish(*, robot: str, address: RobotAddress, instant_actions_key: str, messages: list[Outgoing]) -> None:
    if not messages:
        return
    now = datetime.now(UTC)
    pipe = livestate.client().pipeline(transaction=False)
    for message in messages:
        topic = Topic.ORDER if isinstance(message.content, OrderContent) else Topic.INSTANT_ACTIONS
        header = header_for(address, header_id=livestate.next_header_id(robot, topic), at=now)
        payload = encode(message.content, header, instant_actions_key=instant_actions_key)
        publisher().publish(topic_for(address, topic), payload)
        metrics.count(metrics.MESSAGES_OUT, pipe=pipe, topic=topic.value)
    pipe.execute()
