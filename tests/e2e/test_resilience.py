"""Reference scenarios `server.py` and `start_order.py`, plus crashes, duplicates and malformed messages."""

import time

import orjson
import paho.mqtt.client as mqtt
import pytest
from django.conf import settings

from robots import livestate
from tests.e2e.conftest import BRIDGE, WORKER, Process, simulator_command
from tests.e2e.helpers import (
    create_robot,
    get,
    order_contents,
    post_mission,
    route,
    wait_mission,
    wait_mission_where,
    wait_robot,
)
from tests.faults.checks import carried_leaf
from tests.faults.stack import PrivateBroker
from tests.waiting import wait_for
from workers import metrics

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def long_mission(api, unique, robot: str) -> str:
    name = unique("m")
    legs = [route(f"leg{i}", (x, y)) for i, (x, y) in enumerate([(4, 0), (4, 4), (0, 4), (0, 0)])]
    post_mission(api, name, robot, legs)
    return name


@pytest.mark.parametrize("process", ["worker", "bridge", "beat"])
def test_sigkill_of_a_server_process_mid_mission(api, simulator, unique, stack, recorder, process):
    robot = unique("crash")
    simulator(f"{robot},0,0", extra=("--speed", "4"))
    create_robot(api, robot)
    name = long_mission(api, unique, robot)
    queued = post_mission(api, unique("queued"), robot, [route("r", (1, 1))])["name"]
    wait_for(lambda: get(api, "mission", name)["status"]["current_node"] >= 1, message="second leg")
    stack.processes[process].restart()
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    assert wait_mission(api, queued)["status"]["state"] == "COMPLETED"
    assert (
        get(api, "mission", queued)["status"]["start_timestamp"]
        >= get(api, "mission", name)["status"]["end_timestamp"]
    )
    leaves = {carried_leaf(o) for o in recorder.for_robot(robot, "order")}
    assert len(leaves) == 5  # every leaf went out once, in an order or an update (resends reuse the ids)


def test_broker_restart_mid_mission(api, stack, unique, tmp_path):
    """SIGKILL of the broker mid-mission, and a restart: the mission completes. The broker is the test's own
    (never the machine's, which other tests and processes use), with a bridge, a worker and a simulator
    of the test's own on it; the stack's bridge and worker, which publish to the machine's broker, pause
    meanwhile, so none of this robot's steps goes out where the robot is not."""
    robot = unique("broker")
    with PrivateBroker(tmp_path) as broker:
        env = {**stack.env, "FLEET_MQTT_PORT": str(broker.port)}
        paused = [stack.processes[name] for name in ("bridge", "worker")]
        own = [
            Process("broker-bridge", BRIDGE, env, tmp_path / "bridge.log"),
            Process("broker-worker", WORKER, env, tmp_path / "worker.log"),
            Process(
                "broker-simulator",
                simulator_command(f"{robot},0,0", extra=("--speed", "4", "--mqtt_port", str(broker.port))),
                env,
                tmp_path / "simulator.log",
            ),
        ]
        try:
            for process in paused:
                process.stop()
            for process in own:
                process.start()
            create_robot(api, robot)
            name = long_mission(api, unique, robot)
            wait_for(lambda: get(api, "mission", name)["status"]["current_node"] >= 1, message="second leg")
            broker.kill()  # SIGKILL of the test's own broker only
            time.sleep(1)
            broker.start()
            assert wait_mission(api, name, timeout=90)["status"]["state"] == "COMPLETED"
        finally:
            for process in reversed(own):
                process.stop()
            for process in paused:
                process.start()


def test_simulator_started_late_gets_its_mission(api, simulator, unique):
    robot = unique("late")
    create_robot(api, robot)
    name = post_mission(api, unique("m"), robot, [route("r", (1, 0))])["name"]
    waiting = wait_mission_where(api, name, lambda status: status["waiting_reason"] is not None, timeout=30)
    status = waiting["status"]
    assert (status["state"], status["waiting_reason"]) == ("PENDING", "Robot is offline")
    simulator(f"{robot},0,0")
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"


@pytest.fixture
def publisher():
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
    client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
    client.loop_start()
    yield client
    client.loop_stop()
    client.disconnect()


def test_duplicate_and_out_of_order_states_change_nothing(api, unique, recorder, publisher, simulated_robot):
    robot = simulated_robot("dup")
    first = post_mission(api, unique("first"), robot, [route("a", (1, 0)), route("b", (1, 1))])["name"]
    assert wait_mission(api, first)["status"]["state"] == "COMPLETED"
    sent_for_first = len(recorder.for_robot(robot, "order"))
    topic = f"uagv/v2/RobotCompany/{robot}/state"
    stored = orjson.loads(livestate.latest_state(robot).payload)
    old = {
        **stored,
        "headerId": 0,
        "timestamp": "2020-01-01T00:00:00.000Z",
        "orderId": "stale",
        "nodeStates": [],
    }
    for _ in range(5):
        publisher.publish(topic, orjson.dumps(stored)).wait_for_publish()  # duplicates
        publisher.publish(topic, orjson.dumps(old)).wait_for_publish()  # reordered, older
    second = post_mission(api, unique("second"), robot, [route("c", (0, 0))])["name"]
    assert wait_mission(api, second)["status"]["state"] == "COMPLETED"
    sent = recorder.for_robot(robot, "order")
    # Nothing of the first mission went out again, and each leaf had one order (or its update), resent
    # if at all identically: a resend is the engine's answer to a robot that lacks an order, as a robot
    # on a starved machine seems to, never to duplicate or older states.
    assert {o["orderId"] for o in sent[sent_for_first:]} == {f"{second}-n0-r0"}
    contents = order_contents(sent)
    assert sorted(contents) == sorted([(f"{first}-n0-r0", 0), (f"{first}-n0-r0", 1), (f"{second}-n0-r0", 0)])
    assert all(len(bodies) == 1 for bodies in contents.values())
    assert orjson.loads(livestate.latest_state(robot).payload)["orderId"] != "stale"


def test_malformed_messages_are_counted_and_do_not_stop_the_bridge(api, unique, publisher, simulated_robot):
    robot = simulated_robot("junk")
    wait_robot(api, robot, online=True)

    def invalid() -> int:  # whatever the reason
        counters = livestate.client().hgetall(metrics.COUNTERS)
        return sum(
            int(n)
            for f, n in counters.items()
            if f.startswith(b"messages_invalid|") and f.endswith(b"=state")
        )

    before = invalid()
    for payload in (b"not json", b"[]", b'{"headerId": 1}', b"\xff\xfe"):
        publisher.publish(f"uagv/v2/RobotCompany/{robot}/state", payload).wait_for_publish()
    wait_for(lambda: invalid() >= before + 4, message="invalid messages counted")
    name = post_mission(api, unique("m"), robot, [route("r", (1, 0))])["name"]
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"


def test_metrics_endpoint_exports_fleet_metrics(api, unique, simulated_robot):
    robot = simulated_robot("metrics")
    name = post_mission(api, unique("m"), robot, [route("r", (1, 0))])["name"]
    wait_mission(api, name)
    response = api.get("/metrics")
    assert response.status_code == 200
    text = response.content.decode()
    assert "fleet_messages_in_total" in text
    assert 'fleet_missions_finished_total{failure_category="",state="COMPLETED"}' in text
    assert "fleet_step_latency_seconds_bucket" in text
    assert 'fleet_robots_online{online="true"}' in text
