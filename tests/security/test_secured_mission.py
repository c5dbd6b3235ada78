"""A whole mission over the shipped production broker configuration: bridge, step worker and beat log in as
the dispatcher over TLS, the simulated robot with its own login over TLS, and the ACL lets each do only
its part."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from rest_framework.test import APIClient

from tests.e2e.conftest import Process, simulator_command, start_servers
from tests.e2e.helpers import create_robot, post_mission, route, wait_mission
from tests.security.broker import DISPATCHER, HOST, SecuredBroker

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_a_mission_runs_over_tls_with_the_acl(
    api: APIClient, unique: Callable[[str], str], secured_broker: SecuredBroker, tmp_path: Path
) -> None:
    robot = secured_broker.serial_number("carrier")
    ca_file = str(secured_broker.certificates.ca)
    servers = start_servers(
        tmp_path,
        FLEET_MQTT_HOST=HOST,
        FLEET_MQTT_PORT=str(secured_broker.port),
        FLEET_MQTT_TLS="on",
        FLEET_MQTT_TLS_CA_FILE=ca_file,
        FLEET_MQTT_USERNAME=DISPATCHER,
        FLEET_MQTT_PASSWORD=secured_broker.dispatcher_password,
    )
    broker = ("--mqtt_host", HOST, "--mqtt_port", str(secured_broker.port), "--mqtt_tls", "--mqtt_ca_file")
    login = ("--mqtt_credentials", str(secured_broker.credentials_file))
    simulator = Process(
        "simulator",
        simulator_command(f"{robot},0,0", extra=(*broker, ca_file, *login)),
        servers.env,
        tmp_path / "simulator.log",
    )
    try:
        simulator.start()
        create_robot(api, robot)
        tree = [route("out", (2, 0)), route("back", (0, 0))]
        name = post_mission(api, unique("secured"), robot, tree)["name"]
        assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    finally:
        simulator.stop()
        servers.stop()
        print(f"logs in {tmp_path}")
