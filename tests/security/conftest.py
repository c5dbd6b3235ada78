"""The secured broker of this package's tests: the shipped production Mosquitto configuration on a private
broker, its certificates and robot logins made for the test run."""

from __future__ import annotations

import shutil
import tempfile
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from pytest_django.fixtures import Settings

from tests.e2e.conftest import api, unique  # noqa: F401  (the end-to-end tests' API client and names)
from tests.security.broker import DISPATCHER, HOST, SecuredBroker, make_certificates

ROBOTS = ("robot-a", "robot-b", "carrier")  # each gets its own login, suffixed per run


@contextmanager
def private_secured_broker(
    tmp_path_factory: pytest.TempPathFactory, *, require_certificate: bool = False
) -> Iterator[SecuredBroker]:
    """A running secured broker with a login for each of ROBOTS (serial numbers suffixed per run)."""
    # Not under pytest's base directory: a Mosquitto started as root runs as `mosquitto`, which cannot
    # enter that one.
    directory = Path(tempfile.mkdtemp(prefix="secured-broker-"))
    try:
        broker = SecuredBroker(
            directory, make_certificates(directory / "certificates"), require_certificate=require_certificate
        )
        broker.install()
        suffix = uuid.uuid4().hex[:6]
        for base in ROBOTS:
            broker.add_robot(f"{base}-{suffix}")
        broker.start()
        yield broker
        broker.stop()
    finally:
        log = tmp_path_factory.mktemp("secured-broker") / "broker.log"
        shutil.copy(directory / "broker.log", log)
        shutil.rmtree(directory)
        print(f"secured broker's log: {log}")


@pytest.fixture(scope="package")
def secured_broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SecuredBroker]:
    with private_secured_broker(tmp_path_factory) as broker:
        yield broker


def as_dispatcher(settings: Settings, broker: SecuredBroker) -> Settings:
    """`settings` for this process's server clients (`workers.mqtt.new_client`): the dispatcher over TLS."""
    settings.MQTT_HOST = HOST
    settings.MQTT_PORT = broker.port
    settings.MQTT_TLS = True
    settings.MQTT_TLS_CA_FILE = str(broker.certificates.ca)
    settings.MQTT_USERNAME = DISPATCHER
    settings.MQTT_PASSWORD = broker.dispatcher_password
    return settings


@pytest.fixture
def dispatcher_settings(settings: Settings, secured_broker: SecuredBroker) -> Settings:
    return as_dispatcher(settings, secured_broker)
