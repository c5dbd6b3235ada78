"""The shipped production broker configuration (deploy/mosquitto/) on a private Mosquitto: TLS only, no
anonymous or wrong logins, and the ACL keeps each robot to its own topics while the dispatcher reads all
reports and sends orders. Mosquitto drops what the ACL forbids without telling the client (its acl_file
grants every SUBSCRIBE and filters deliveries), so each refusal is shown by what never arrives while the
allowed message sent after it does."""

from __future__ import annotations

import argparse
import ssl
import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion
from pytest_django.fixtures import Settings

from simulator.cli import add_broker_arguments, shared_broker_settings
from simulator.monitor import FleetTraffic, watch
from simulator.runner import BrokerSettings
from tests.security.broker import DISPATCHER, HOST, SecuredBroker
from tests.security.conftest import as_dispatcher, private_secured_broker
from tests.waiting import wait_for
from tests.workers.subscriber import subscribed
from workers.mqtt import new_client

pytestmark = pytest.mark.e2e

CONNECT_SECONDS = 10.0


def connack(client: mqtt.Client, host: str, port: int) -> Any:
    """Connect and return the broker's CONNACK reason code, or None if it closed the connection (or the TLS
    handshake failed on its side) without one."""
    answers: list[Any] = []
    answered = threading.Event()

    def on_connect(client: mqtt.Client, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        answers.append(reason)
        answered.set()

    client.on_connect = on_connect
    client.on_disconnect = lambda *args: answered.set()
    client.connect(host, port)
    client.loop_start()
    assert answered.wait(CONNECT_SECONDS), "neither CONNACK nor a closed connection"
    return answers[0] if answers else None


class Robot:
    """A robot's connection as the simulator makes it (its TLS settings and login), recording what it gets."""

    def __init__(
        self, broker: SecuredBroker, username: str | None, password: str | None, *, tls: bool = True
    ) -> None:
        self.serial = username or ""  # a robot logs in with its serial number
        self.settings = BrokerSettings(
            host=HOST,
            port=broker.port,
            username=username,
            password=password,
            tls=tls,
            ca_file=str(broker.certificates.ca),
        )
        self.received: list[tuple[str, bytes]] = []
        self.subscribed = threading.Event()
        self.client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=f"test-{uuid.uuid4().hex[:8]}",
            protocol=MQTTProtocolVersion.MQTTv311,
        )
        context = self.settings.tls_context()
        if context is not None:
            self.client.tls_set_context(context)
        login = self.settings.login(self.serial)
        if login is not None:
            self.client.username_pw_set(login.username, login.password)
        self.client.on_subscribe = lambda *args: self.subscribed.set()
        self.client.on_message = lambda client, userdata, message: self.received.append(
            (message.topic, message.payload)
        )

    def connect(self) -> Any:
        """The broker's CONNACK reason code, or None if it closed the connection without one."""
        return connack(self.client, self.settings.host, self.settings.port)

    def subscribe(self, *topics: str) -> None:
        self.subscribed.clear()
        self.client.subscribe([(topic, 1) for topic in topics])
        assert self.subscribed.wait(CONNECT_SECONDS)

    def publish(self, topic: str, payload: bytes) -> None:
        self.client.publish(topic, payload, qos=1).wait_for_publish(CONNECT_SECONDS)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


@pytest.fixture
def robots(secured_broker: SecuredBroker) -> Iterator[list[Robot]]:
    """Two robots connected with their own logins."""
    serials = [secured_broker.serial_number(base) for base in ("robot-a", "robot-b")]
    connected = [Robot(secured_broker, serial, secured_broker.robots[serial].password) for serial in serials]
    for robot in connected:
        assert not robot.connect().is_failure
    yield connected
    for robot in connected:
        robot.close()


def topic(serial: str, kind: str) -> str:
    return f"uagv/v2/RobotCompany/{serial}/{kind}"


def test_a_robot_cannot_publish_another_robots_state(
    dispatcher_settings: Settings, robots: list[Robot]
) -> None:
    robot, other = robots
    with subscribed("uagv/v2/RobotCompany/+/state") as states:  # the dispatcher, as the bridge subscribes
        robot.publish(topic(other.serial, "state"), b"forged")
        robot.publish(topic(robot.serial, "state"), b"own")
        other.publish(topic(other.serial, "state"), b"other's own")
        wait_for(lambda: b"own" in states and b"other's own" in states, "the robots' own states")
    assert b"forged" not in states


@pytest.mark.parametrize("kind", ["order", "instantActions"])
def test_a_robot_cannot_read_another_robots_orders(
    dispatcher_settings: Settings, robots: list[Robot], kind: str
) -> None:
    robot, other = robots
    robot.subscribe(topic(other.serial, kind), f"+/+/+/+/{kind}", topic(robot.serial, kind))
    other.subscribe(topic(other.serial, kind))
    dispatcher = new_client("test-dispatcher")
    dispatcher.connect(dispatcher_settings.MQTT_HOST, dispatcher_settings.MQTT_PORT)
    dispatcher.loop_start()
    try:
        dispatcher.publish(topic(other.serial, kind), b"for the other", qos=1).wait_for_publish(10)
        dispatcher.publish(topic(robot.serial, kind), b"for the robot", qos=1).wait_for_publish(10)
        wait_for(lambda: other.received and robot.received, "each robot's own message")
    finally:
        dispatcher.disconnect()
        dispatcher.loop_stop()
    assert other.received == [(topic(other.serial, kind), b"for the other")]
    # Its own message (through its exact and its wildcard subscription), never the other robot's.
    assert {payload for _, payload in robot.received} == {b"for the robot"}


@pytest.mark.parametrize(
    "login",
    [(None, None), ("nobody", "anything"), ("robot", "wrong password")],
    ids=["anonymous", "unknown user", "wrong password"],
)
def test_a_robot_without_its_credentials_cannot_connect(
    secured_broker: SecuredBroker, login: tuple[str | None, str | None]
) -> None:
    username, password = login
    if username == "robot":
        username = secured_broker.serial_number("robot-a")
    robot = Robot(secured_broker, username, password)
    try:
        reason = robot.connect()
        assert reason is not None and reason.is_failure, reason
    finally:
        robot.close()


def test_plain_mqtt_is_not_served_on_the_tls_listener(secured_broker: SecuredBroker) -> None:
    serial = secured_broker.serial_number("robot-a")
    robot = Robot(secured_broker, serial, secured_broker.robots[serial].password, tls=False)
    try:
        assert robot.connect() is None  # the broker closed the connection: no CONNACK
    finally:
        robot.close()


def test_the_dispatcher_checks_the_brokers_certificate(dispatcher_settings: Settings) -> None:
    """A CA that did not sign the broker's certificate, or a host name it was not issued for (127.0.0.1;
    it names `localhost`), fail the TLS handshake; with host names unchecked the name passes."""
    secured = dispatcher_settings.MQTT_TLS_CA_FILE
    dispatcher_settings.MQTT_TLS_CA_FILE = secured.replace("ca.crt", "other-ca.crt")
    with pytest.raises(ssl.SSLCertVerificationError, match="certificate verify failed"):
        new_client("test").connect(HOST, dispatcher_settings.MQTT_PORT)
    dispatcher_settings.MQTT_TLS_CA_FILE = secured
    with pytest.raises(ssl.SSLCertVerificationError, match="IP address mismatch"):
        new_client("test").connect("127.0.0.1", dispatcher_settings.MQTT_PORT)
    dispatcher_settings.MQTT_TLS_CHECK_HOSTNAME = False
    client = new_client("test")
    assert client.connect("127.0.0.1", dispatcher_settings.MQTT_PORT) == mqtt.MQTT_ERR_SUCCESS
    client.disconnect()


def test_a_client_certificate_goes_along_when_configured(
    settings: Settings, tmp_path_factory: pytest.TempPathFactory
) -> None:
    """deploy/README.md's variant with client certificates required: without one the broker ends the
    connection; with FLEET_MQTT_TLS_CERT_FILE/KEY_FILE the dispatcher is let in."""
    with private_secured_broker(tmp_path_factory, require_certificate=True) as broker:
        as_dispatcher(settings, broker)
        without = new_client("test")
        try:
            assert connack(without, HOST, broker.port) is None
        finally:
            without.loop_stop()
        settings.MQTT_TLS_CERT_FILE = str(broker.certificates.client_cert)
        settings.MQTT_TLS_KEY_FILE = str(broker.certificates.client_key)
        with_certificate = new_client("test")
        try:
            reason = connack(with_certificate, HOST, broker.port)
            assert reason is not None and not reason.is_failure, reason
        finally:
            with_certificate.disconnect()
            with_certificate.loop_stop()


def test_the_traffic_monitor_watches_every_robot_over_tls_with_the_dispatchers_login(
    secured_broker: SecuredBroker, robots: list[Robot]
) -> None:
    args = argparse.ArgumentParser()
    add_broker_arguments(args)
    options = args.parse_args(
        [
            *("--mqtt_host", HOST, "--mqtt_port", str(secured_broker.port), "--mqtt_tls"),
            *("--mqtt_ca_file", str(secured_broker.certificates.ca)),
            *("--mqtt_username", DISPATCHER, "--mqtt_password", secured_broker.dispatcher_password),
        ]
    )
    robot, other = robots
    watched: list[FleetTraffic] = []
    broker = shared_broker_settings(options)
    watcher = threading.Thread(target=lambda: watched.append(watch(broker, "uagv", seconds=6.0)))
    watcher.start()
    for header_id in range(1, 21):  # over 4 s: the monitor connects meanwhile and sees the later ones
        robot.publish(topic(robot.serial, "state"), orjson.dumps({"headerId": header_id}))
        other.publish(topic(other.serial, "state"), orjson.dumps({"headerId": header_id}))
        time.sleep(0.2)
    watcher.join()

    traffic = watched[0].robots
    for serial in (robot.serial, other.serial):
        assert traffic[serial].states >= 5
        assert traffic[serial].skipped_header_ids == 0
