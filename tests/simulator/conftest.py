"""Harnesses for the simulator: a robot model on a fake clock, and MQTT probes for the real process.

Every message the simulator publishes in these tests is validated against the official JSON schema.
"""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import threading
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion

from simulator.config import RobotConfig, SimulationSettings, parse_robot_spec
from simulator.outbox import Publication
from simulator.robot import SimulatedRobot
from tests.vda5050.schemas import validate_message
from tests.waiting import wait_for
from vda5050.codec import encode, header_for, parse_state
from vda5050.models import (
    Action,
    ActionParameter,
    ActionState,
    AgvClass,
    BlockingType,
    Header,
    InstantActionsContent,
    OrderContent,
    State,
    StateContent,
)
from vda5050.orders import Pose, Waypoint, cancel_order, instant_action, route_order
from vda5050.topics import RobotAddress, Topic

ROOT = Path(__file__).resolve().parents[2]
T0 = 1_800_000_000.0  # the fake clock's start (UNIX seconds)
WAIT_SECONDS = 30.0  # generous: the machine is shared; nothing asserts on durations
MQTT_HOST = "127.0.0.1"
MQTT_PORT = 1883
STANDARD_AGV_CLASSES = {agv_class.value for agv_class in AgvClass}


def validate(kind: str, message: dict[str, Any]) -> None:
    """Official schema check. Isaac's MANIPULATOR/HUMANOID agvClass is outside the 2.x enum on purpose
    (Dispatch filters robots by it), so only that one field is exempt (3.0's mobileRobotClass is free)."""
    if (
        kind == Topic.FACTSHEET
        and message["typeSpecification"].get("agvClass", "CARRIER") not in STANDARD_AGV_CLASSES
    ):
        message = orjson.loads(orjson.dumps(message))
        message["typeSpecification"]["agvClass"] = AgvClass.CARRIER.value
    validate_message(kind, message["version"], message)


def action(action_type: str, action_id: str, **parameters: Any) -> Action:
    return Action(
        action_type=action_type,
        action_id=action_id,
        blocking_type=BlockingType.HARD,
        action_parameters=[ActionParameter(key=key, value=value) for key, value in parameters.items()]
        or None,
    )


def route(
    *targets: tuple[float, float],
    start: tuple[float, float] = (0.0, 0.0),
    mission: str = "m1",
    horizon: tuple[tuple[float, float], ...] = (),
    deviation_xy: float = 0.0,
) -> OrderContent:
    """An order from ``start`` through ``targets`` (heading 0), as Dispatch builds it."""
    return route_order(
        mission=mission,
        node_index=0,
        attempt=0,
        start=Pose(*start, 0.0, "map"),
        waypoints=[Waypoint(x, y, 0.0, "map", allowed_deviation_xy=deviation_xy) for x, y in targets],
        horizon=[Waypoint(x, y, 0.0, "map", allowed_deviation_xy=deviation_xy) for x, y in horizon],
    )


class RobotHarness:
    """One SimulatedRobot, a fake clock, and every message it sent (each validated)."""

    def __init__(self, spec: str = "carter01,0,0", **settings: Any) -> None:
        self.config: RobotConfig = parse_robot_spec(spec)
        self.settings = SimulationSettings(**settings)
        self.now = T0
        self.robot = SimulatedRobot(self.config, self.settings, now=self.now)
        self.sent: list[Publication] = []
        self._header_ids = itertools.count()
        self.record(self.robot.connected(self.now))

    def record(self, messages: list[Publication]) -> list[Publication]:
        for message in messages:
            validate(message.kind, orjson.loads(message.payload))
        self.sent += messages
        return messages

    def header(self, **overrides: Any) -> Header:
        header = header_for(self.robot.address, header_id=next(self._header_ids), at=datetime.now(UTC))
        return header.model_copy(update=overrides)

    def send_order(self, order: OrderContent | bytes, **header_overrides: Any) -> list[Publication]:
        payload = order if isinstance(order, bytes) else encode(order, self.header(**header_overrides))
        return self.record(self.robot.receive(Topic.ORDER, payload, self.now))

    def send_actions(self, *actions: Action, **header_overrides: Any) -> list[Publication]:
        payload = encode(InstantActionsContent(actions=list(actions)), self.header(**header_overrides))
        return self.record(self.robot.receive(Topic.INSTANT_ACTIONS, payload, self.now))

    def tick(self, count: int = 1) -> list[Publication]:
        messages = []
        for _ in range(count):
            self.now += self.settings.tick_period
            messages += self.record(self.robot.tick(self.now))
        return messages

    def run(self, seconds: float) -> list[Publication]:
        return self.tick(math.ceil(seconds / self.settings.tick_period - 1e-9))

    def run_until(
        self, condition: Callable[[StateContent], bool], max_seconds: float = 120.0
    ) -> StateContent:
        for _ in range(math.ceil(max_seconds / self.settings.tick_period)):
            if condition(self.state):
                return self.state
            self.tick()
        pytest.fail("the robot never reached the expected state")

    @property
    def state(self) -> StateContent:
        return self.robot.state_content()

    def action_state(self, action_id: str) -> ActionState:
        return next(a for a in self.state.action_states if a.action_id == action_id)

    def states(self, messages: list[Publication] | None = None) -> list[State]:
        return [
            parse_state(m.payload)
            for m in (self.sent if messages is None else messages)
            if m.kind == Topic.STATE
        ]


@pytest.fixture
def harness() -> Callable[..., RobotHarness]:
    return RobotHarness


def keep_busy(h: RobotHarness) -> None:
    """Three seconds of everything a robot sends: an order with a pick and a failing action, a message
    that is no order, and instant actions it runs, refuses and does not know (NONE-blocking, as 3.0
    requires)."""
    order = route((1, 0), (1, 1), horizon=((2, 2),))
    order.nodes[1].actions += [
        action("pick", "p", loadId="l1"),
        action("dummy_action", "f", should_fail=1, time=0),
    ]
    h.send_order(order)
    h.send_order(b"{}")
    h.send_actions(
        instant_action("factsheetRequest", "fr"), cancel_order("c"), instant_action("unknown", "u")
    )
    h.run(3.0)


# --- MQTT ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Received:
    topic: str
    body: dict[str, Any]
    retained: bool

    @property
    def serial(self) -> str:
        return self.topic.split("/")[3]

    @property
    def kind(self) -> str:
        return self.topic.rsplit("/", 1)[1]


class MqttProbe:
    """Subscribes to everything under one interface name (unique per test) and records it."""

    def __init__(self, interface_name: str) -> None:
        self.interface_name = interface_name
        self._received: list[Received] = []
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"probe-{uuid.uuid4().hex[:10]}")
        self.client.on_connect = lambda client, *_: client.subscribe(f"{interface_name}/#", qos=1)
        self.client.on_subscribe = lambda *_: self._subscribed.set()
        self.client.on_message = self._on_message
        self.client.connect(MQTT_HOST, MQTT_PORT)
        self.client.loop_start()
        assert self._subscribed.wait(WAIT_SECONDS), "probe could not subscribe"

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        if message.payload:  # an empty payload clears a retained message
            with self._lock:
                self._received.append(Received(message.topic, orjson.loads(message.payload), message.retain))

    def received(self, kind: str | None = None, serial: str | None = None) -> list[Received]:
        with self._lock:
            return [
                r
                for r in self._received
                if (kind is None or r.kind == kind) and (serial is None or r.serial == serial)
            ]

    def wait_for(self, condition: Callable[[Received], bool], message: str) -> Received:
        return wait_for(lambda: next((r for r in self.received() if condition(r)), None), message)

    def publish(self, topic: str, payload: bytes) -> None:
        self.client.publish(topic, payload, qos=0).wait_for_publish(WAIT_SECONDS)

    def validate_all(self) -> None:
        for received in self.received():
            validate(received.kind, received.body)

    def clear_retained(self) -> None:
        """The broker persists retained messages; leave nothing behind."""
        topics = {r.topic for r in self.received() if r.kind in (Topic.CONNECTION, Topic.FACTSHEET)}
        for topic in topics:
            self.client.publish(topic, b"", qos=1, retain=True).wait_for_publish(WAIT_SECONDS)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class SimulatorProcess:
    """``python -m simulator`` as a child process."""

    def __init__(self, interface_name: str, args: list[str], log: Path) -> None:
        self.interface_name = interface_name
        self.log = log
        with log.open("wb") as output:
            self.popen = subprocess.Popen(
                [sys.executable, "-m", "simulator", "--interface_name", interface_name, *args],
                cwd=ROOT,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
                stdout=output,
                stderr=subprocess.STDOUT,
            )

    def address(
        self, serial: str, version: str = "2.0.0", manufacturer: str = "RobotCompany"
    ) -> RobotAddress:
        return RobotAddress(self.interface_name, manufacturer, serial, version)

    def signal(self, signum: int) -> int:
        self.popen.send_signal(signum)
        return self.popen.wait(WAIT_SECONDS)

    def stop(self) -> None:
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGTERM)
            try:
                self.popen.wait(WAIT_SECONDS)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()


@pytest.fixture
def interface_name() -> str:
    return f"sim{uuid.uuid4().hex[:10]}"


@pytest.fixture
def probe(interface_name: str) -> Iterator[MqttProbe]:
    probe = MqttProbe(interface_name)
    yield probe
    probe.clear_retained()
    probe.close()


@pytest.fixture
def start_simulator(
    interface_name: str, probe: MqttProbe, tmp_path: Path
) -> Iterator[Callable[..., SimulatorProcess]]:
    """Start the simulator (topics under this test's interface name); stopped and its traffic
    validated when the test ends."""
    processes: list[SimulatorProcess] = []

    def start(*args: str) -> SimulatorProcess:
        process = SimulatorProcess(interface_name, list(args), tmp_path / f"simulator-{len(processes)}.log")
        processes.append(process)
        return process

    yield start
    for process in processes:
        process.stop()
    probe.validate_all()
