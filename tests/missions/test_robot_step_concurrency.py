"""Steps of one robot are serialized: concurrent steps never send an order twice or skip a transition."""

import threading
import time
import uuid
from collections.abc import Iterator
from datetime import UTC, datetime

import pytest
from django.db import connection

from dispatch.held import state_digest
from missions.robot_step import robot_step
from missions.services import mission_create
from robots import livestate
from robots.models import Robot
from robots.services import robot_create
from tests.factories import TEST_ACTOR
from vda5050.codec import encode, header_for, parse_state
from vda5050.models import (
    AgvPosition,
    BatteryState,
    EStop,
    OperatingMode,
    SafetyState,
    StateContent,
)
from vda5050.topics import RobotAddress

pytestmark = pytest.mark.django_db(transaction=True)


def idle_state(robot: str, header_id: int) -> bytes:
    content = StateContent(
        order_id="",
        order_update_id=0,
        last_node_id="",
        last_node_sequence_id=0,
        driving=False,
        operating_mode=OperatingMode.AUTOMATIC,
        node_states=[],
        edge_states=[],
        agv_position=AgvPosition(x=0, y=0, theta=0, map_id="map", position_initialized=True),
        action_states=[],
        battery_state=BatteryState(battery_charge=80, charging=False),
        errors=[],
        safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
    )
    address = RobotAddress("uagv", "RobotCompany", robot)
    return encode(content, header_for(address, header_id=header_id, at=datetime.now(UTC)))


@pytest.fixture
def online_robot() -> Iterator[str]:
    name = f"conc-{uuid.uuid4().hex[:8]}"
    robot_create(actor=TEST_ACTOR, name=name, prefix=None, spec={})
    Robot.objects.filter(name=name).update(online=True)
    pipe = livestate.client().pipeline()
    payload = idle_state(name, 1)
    digest = state_digest(parse_state(payload))
    livestate.store_state(
        pipe, name=name, payload=payload, timestamp_ms=1, header_id=1, digest=digest, arrived_at=time.time()
    )
    livestate.execute(pipe)
    yield name
    livestate.forget(name)


def test_concurrent_steps_of_one_robot_send_the_first_order_once(online_robot: str) -> None:
    route = {"name": "r", "route": {"waypoints": [{"x": 1, "y": 0}]}}
    mission_create(
        actor=TEST_ACTOR, name=None, prefix="m", spec={"robot": online_robot, "mission_tree": [route]}
    )
    barrier = threading.Barrier(4)
    sent: list[str] = []
    lock = threading.Lock()

    def step() -> None:
        try:
            barrier.wait()
            outcome = robot_step(name=online_robot)
            with lock:
                sent.extend(m.content.order_id for m in outcome.messages if hasattr(m.content, "order_id"))
        finally:
            connection.close()

    threads = [threading.Thread(target=step) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    assert len(sent) == 1
    assert Robot.objects.get(name=online_robot).state == "ON_TASK"
