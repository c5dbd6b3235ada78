"""Publishing a step's messages (`workers.publish`) against the real Redis and broker: each headerId goes
out once, however many steps hold it."""

import uuid
from collections.abc import Iterator

import pytest

from missions.robot_step import WireMessage
from robots import livestate
from tests.waiting import wait_for
from tests.workers.subscriber import subscribed
from vda5050.topics import RobotAddress, Topic, topic_for
from workers.publish import publish


@pytest.fixture
def address() -> Iterator[RobotAddress]:
    name = f"publish-{uuid.uuid4().hex[:8]}"
    yield RobotAddress("uagv", "RobotCompany", name)
    livestate.forget(name)


@pytest.fixture
def orders(address: RobotAddress) -> Iterator[list[bytes]]:
    """The payloads the broker delivers on the robot's order topic, in order."""
    with subscribed(topic_for(address, Topic.ORDER)) as payloads:
        yield payloads


def send(address: RobotAddress, *messages: WireMessage) -> None:
    pipe = livestate.client().pipeline()
    publish(name=address.serial_number, address=address, messages=list(messages), counters=pipe)
    pipe.execute()


def test_a_message_two_steps_hold_goes_out_once(address: RobotAddress, orders: list[bytes]) -> None:
    """A step sends again what an earlier one may not have sent (its outbox); the earlier one may still be
    at it. Whichever claims a headerId first sends it."""
    first, second = WireMessage(Topic.ORDER, 0, b'{"n": 0}'), WireMessage(Topic.ORDER, 1, b'{"n": 1}')

    send(address, first)
    send(address, first, second)  # the later step, with the earlier one's message from the outbox

    wait_for(lambda: len(orders) == 2)
    assert orders == [b'{"n": 0}', b'{"n": 1}']
    assert livestate.latest_state(address.serial_number).published == {"order": 1}
