"""The server's MQTT clients and the simulator over websockets over TLS (wss). Debian 12's Mosquitto is
built without websockets, so the broker here is amqtt with a wss listener only, holding a certificate made
for the test."""

from __future__ import annotations

import json
import os
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from pytest_django.fixtures import Settings

from tests.e2e.conftest import simulator_command
from tests.faults.stack import Proc, free_port, port_open, wait_until
from tests.security.broker import HOST, make_certificates
from tests.waiting import wait_for
from tests.workers.subscriber import subscribed
from workers.mqtt import Publisher

pytestmark = pytest.mark.e2e

AMQTT = str(Path(sys.executable).with_name("amqtt"))


@pytest.fixture(scope="module")
def wss_settings(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, object]]:
    """An amqtt broker whose only listener is wss, and the settings that reach it."""
    directory = tmp_path_factory.mktemp("wss-broker")
    certificates = make_certificates(directory / "certificates")
    port = free_port()
    listener = {
        "type": "ws",
        "bind": f"127.0.0.1:{port}",
        "ssl": True,
        "certfile": str(certificates.server_cert),
        "keyfile": str(certificates.server_key),
    }
    config = directory / "amqtt.yaml"  # JSON is YAML
    config.write_text(json.dumps({"listeners": {"default": listener}}))
    broker = Proc("wss-broker", [AMQTT, "-c", str(config)], dict(os.environ), directory / "broker.log")
    broker.start()
    try:
        wait_until(lambda: port_open(port), f"amqtt's wss listener on port {port}", timeout=30)
        yield {
            "MQTT_HOST": HOST,
            "MQTT_PORT": port,
            "MQTT_TRANSPORT": "websockets",
            "MQTT_TLS": True,
            "MQTT_TLS_CA_FILE": str(certificates.ca),
        }
    finally:
        broker.stop()


def test_server_clients_exchange_messages_over_wss(
    settings: Settings, wss_settings: dict[str, object]
) -> None:
    for name, value in wss_settings.items():
        setattr(settings, name, value)
    topic = f"test/wss/{uuid.uuid4().hex}"
    with subscribed(topic) as payloads:  # connected and subscribed over wss
        publisher = Publisher()
        try:
            assert publisher.wait_connected(10)
            assert publisher.publish(topic, b"over wss")
            wait_for(lambda: payloads == [b"over wss"], "the message over wss")
        finally:
            publisher._client.disconnect()
            publisher._client.loop_stop()


def test_a_simulated_robot_reports_over_wss(
    settings: Settings, wss_settings: dict[str, object], tmp_path: Path
) -> None:
    for name, value in wss_settings.items():
        setattr(settings, name, value)
    robot = f"wss-{uuid.uuid4().hex[:6]}"
    wss = ("--mqtt_transport", "websockets", "--mqtt_tls", "--mqtt_ca_file", str(settings.MQTT_TLS_CA_FILE))
    broker = ("--mqtt_host", HOST, "--mqtt_port", str(settings.MQTT_PORT), *wss)
    with subscribed(f"uagv/v2/RobotCompany/{robot}/state") as states:
        argv = simulator_command(f"{robot},0,0", extra=broker)
        simulator = Proc("simulator", argv, dict(os.environ), tmp_path / "simulator.log")
        simulator.start()
        try:
            wait_for(lambda: len(states) >= 2, "the robot's states over wss")
        finally:
            simulator.stop()
