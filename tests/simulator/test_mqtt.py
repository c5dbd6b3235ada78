"""The simulator process over the real Mosquitto: orders, last will, clean shutdown, factsheet, scale."""

from __future__ import annotations

import signal
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from tests.simulator.conftest import MqttProbe, action, route
from tests.waiting import wait_for
from vda5050.codec import encode, header_for
from vda5050.models import InstantActionsContent
from vda5050.topics import Topic, topic_for

FAST = ("--speed", "10", "--tick_period", "0.05", "--state_period", "0.5")


def is_online(serial: str):
    return lambda r: (
        r.kind == Topic.CONNECTION and r.serial == serial and r.body["connectionState"] == "ONLINE"
    )


def test_order_is_driven_to_completion_with_progress_in_state_messages(start_simulator, probe) -> None:
    simulator = start_simulator("--robots", "carter01,0,0", *FAST)
    probe.wait_for(is_online("carter01"), "the robot to come online")
    address = simulator.address("carter01")
    order = route((2, 0), (2, 2))
    header = header_for(address, header_id=0, at=datetime.now(UTC))
    probe.publish(topic_for(address, Topic.ORDER), encode(order, header))

    done = probe.wait_for(
        lambda r: (
            r.kind == Topic.STATE
            and r.body["orderId"] == order.order_id
            and r.body["lastNodeSequenceId"] == 4
            and not r.body["nodeStates"]
            and not r.body["driving"]
        ),
        "the order to complete",
    )
    assert done.body["agvPosition"]["x"] == 2.0 and done.body["agvPosition"]["y"] == 2.0
    states = [r.body for r in probe.received(Topic.STATE) if r.body["orderId"] == order.order_id]
    assert any(s["driving"] and s["lastNodeSequenceId"] == 0 for s in states)  # set off from the start node
    assert any(s["lastNodeSequenceId"] == 2 and len(s["nodeStates"]) == 1 for s in states)  # halfway
    header_ids = [r.body["headerId"] for r in probe.received(Topic.STATE)]
    assert header_ids == list(range(header_ids[0], header_ids[0] + len(header_ids)))


def test_sigkill_leaves_a_retained_connection_broken(start_simulator, probe, interface_name) -> None:
    simulator = start_simulator("--robots", "carter01,0,0", "carter02,1,1")
    probe.wait_for(is_online("carter02"), "the robots to come online")
    simulator.signal(signal.SIGKILL)
    for serial in ("carter01", "carter02"):
        probe.wait_for(
            lambda r, s=serial: (
                r.kind == Topic.CONNECTION
                and r.serial == s
                and r.body["connectionState"] == "CONNECTIONBROKEN"
            ),
            f"the last will of {serial}",
        )
    late_subscriber = MqttProbe(interface_name)
    try:
        retained = late_subscriber.wait_for(lambda r: r.kind == Topic.CONNECTION, "the retained connection")
    finally:
        late_subscriber.close()
    assert retained.retained and retained.body["connectionState"] == "CONNECTIONBROKEN"


def test_sigterm_publishes_offline_then_exits(start_simulator, probe) -> None:
    simulator = start_simulator("--robots", "carter01,0,0")
    online = probe.wait_for(is_online("carter01"), "the robot to come online")
    assert simulator.signal(signal.SIGTERM) == 0
    offline = probe.wait_for(
        lambda r: r.kind == Topic.CONNECTION and r.body["connectionState"] == "OFFLINE", "OFFLINE"
    )
    assert offline.body["headerId"] > online.body["headerId"]
    assert not any(r.body["connectionState"] == "CONNECTIONBROKEN" for r in probe.received(Topic.CONNECTION))


def test_factsheet_is_published_on_request(start_simulator, probe) -> None:
    simulator = start_simulator(
        "--robots", "arm01,0,0,0,map,0,20,RobotCompany,arm01,MANIPULATOR", "--vda_version", "2.1.0"
    )
    probe.wait_for(is_online("arm01"), "the robot to come online")
    first = probe.wait_for(lambda r: r.kind == Topic.FACTSHEET, "the factsheet published on connect")
    address = simulator.address("arm01", version="2.1.0")
    request = InstantActionsContent(actions=[action("factsheetRequest", "fr-1")])
    probe.publish(
        topic_for(address, Topic.INSTANT_ACTIONS),
        encode(request, header_for(address, header_id=0, at=datetime.now(UTC))),
    )
    answer = probe.wait_for(
        lambda r: r.kind == Topic.FACTSHEET and r.body["headerId"] > first.body["headerId"],
        "the requested factsheet",
    )
    assert answer.body["typeSpecification"]["agvClass"] == "MANIPULATOR"
    assert answer.body["physicalParameters"]["speedMax"] == 0
    probe.wait_for(
        lambda r: (
            r.kind == Topic.STATE
            and any(
                a["actionId"] == "fr-1" and a["actionStatus"] == "FINISHED" for a in r.body["actionStates"]
            )
        ),
        "factsheetRequest FINISHED",
    )


def serials_with(probe: MqttProbe, kind: str, condition: Callable[[dict[str, Any]], bool]) -> set[str]:
    return {r.serial for r in probe.received(kind) if condition(r.body)}


def test_hundreds_of_robots_in_one_process_come_online_and_publish_state(start_simulator, probe) -> None:
    count = 250
    start_simulator("--count", str(count), "--name-prefix", "fleet", "--visualization_period", "0")
    serials = {f"fleet{index:03d}" for index in range(1, count + 1)}
    wait_for(
        lambda: (
            serials_with(probe, Topic.CONNECTION, lambda body: body["connectionState"] == "ONLINE") == serials
        ),
        f"{count} robots ONLINE",
    )
    wait_for(
        lambda: serials_with(probe, Topic.STATE, lambda body: body["headerId"] >= 2) == serials,
        f"{count} robots publishing state periodically",
    )
