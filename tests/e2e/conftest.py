"""End-to-end harness: real bridge, worker, beat and simulator processes against the test database.

The server processes start once for this package (restartable by tests that kill them); each test starts its
own simulator with robots named uniquely, so tests never see each other's robots. Every order and instant
action published during the session is recorded and validated against the official JSON schema.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
from django.conf import settings
from django.core.management.base import CommandError
from django.db import DatabaseError, connection
from django.test import TransactionTestCase
from rest_framework.test import APIClient

from tests.conftest import authenticated_client
from tests.granian_server import ASGI, granian_command
from tests.private_redis import free_port
from tests.server_env import SERVER_ENV
from tests.vda5050.schemas import validate_message

ROOT = Path(__file__).resolve().parents[2]
PYTHON = sys.executable
CELERY = str(Path(PYTHON).with_name("celery"))
WAIT_SECONDS = 60.0  # generous: the machine is shared; nothing asserts on durations

# Command lines of the scalable server processes; a test may start more of them (test_scale_out.py).
BRIDGE = [PYTHON, "manage.py", "mqtt_bridge"]
WORKER = [
    CELERY,
    "-A",
    "fleet",
    "worker",
    "-Q",
    "steps,notify",
    "--pool",
    "threads",
    "--concurrency",
    "4",
    "--without-heartbeat",
    "--without-gossip",
    "--without-mingle",
]


def _flush_retrying_on_deadlock(self: TransactionTestCase) -> None:
    """The flush after a test can deadlock with a step the worker is still running for that test's robot;
    PostgreSQL then aborts one of them. The step is retried by the engine; the flush is retried here.
    Django's flush command reports the database's error as a CommandError caused by it."""
    for attempt in range(5):
        try:
            _flush(self)
            return
        except (DatabaseError, CommandError) as error:
            database_error = error if isinstance(error, DatabaseError) else error.__cause__
            if attempt == 4 or not isinstance(database_error, DatabaseError):
                raise
            time.sleep(0.5)


_flush = TransactionTestCase._fixture_teardown
TransactionTestCase._fixture_teardown = _flush_retrying_on_deadlock


@dataclass
class Process:
    name: str
    argv: list[str]
    env: dict[str, str]
    log: Path
    popen: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        with self.log.open("ab") as log:
            self.popen = subprocess.Popen(
                self.argv,
                cwd=ROOT,
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )

    def running(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    def send(self, sig: int) -> None:
        if self.running():
            os.killpg(self.popen.pid, sig)

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Send `sig` (SIGKILL by default) and wait for the process to end; SIGKILL it if it does not."""
        self.send(sig)
        if self.popen is None:
            return
        try:
            self.popen.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.send(signal.SIGKILL)
            self.popen.wait(timeout=30)

    def stop(self) -> None:
        self.kill(signal.SIGTERM)

    def restart(self) -> None:
        self.kill()
        self.start()

    def output(self) -> str:
        """Everything the process has logged so far."""
        return self.log.read_text(errors="replace")


@contextmanager
def running(process: Process) -> Iterator[Process]:
    """`process` (a robot stack of a third party, say) started while the block runs, then stopped; its output
    printed, for the test's report."""
    process.start()
    try:
        yield process
    finally:
        process.stop()
        print(process.output())


@dataclass
class Stack:
    env: dict[str, str]
    logs: Path
    processes: dict[str, Process] = field(default_factory=dict)
    api_port: int = field(default_factory=free_port)

    @property
    def api_url(self) -> str:
        """The API process (REST and streams), as deploy/Procfile runs it; tests call REST in-process."""
        return f"http://127.0.0.1:{self.api_port}"

    def add(self, name: str, argv: list[str]) -> Process:
        process = Process(name, argv, self.env, self.logs / f"{name}.log")
        process.start()
        self.processes[name] = process
        return process

    def stop(self) -> None:
        for process in self.processes.values():
            process.stop()

    @contextmanager
    def reconfigured(self, *names: str, **overrides: str) -> Iterator[None]:
        """The processes `names` (worker, beat ...) restarted with more settings while the block runs, then
        again as before: a setting for a few tests only, without a second stack on the same database."""
        for name in names:
            self._replace(name, {**self.env, **overrides})
        try:
            yield
        finally:
            for name in names:
                self._replace(name, self.env)

    def _replace(self, name: str, env: dict[str, str]) -> None:
        old = self.processes[name]
        old.stop()
        self.processes[name] = Process(name, old.argv, env, old.log)
        self.processes[name].start()


class Recorder:
    """Every message the server publishes to robots (orders, instant actions, 3.0 zone sets and responses)
    while the end-to-end tests run: each is checked against its schema at the end."""

    def __init__(self) -> None:
        self.messages: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.Lock()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=f"recorder-{uuid.uuid4().hex[:8]}"
        )
        # This run's interface, and the one some tests give their robots as the AGVs they run use: not
        # another run's on the same broker (a developer's suites side by side).
        interfaces = sorted({settings.VDA5050_INTERFACE_NAME, "uagv"})
        self.client.on_connect = lambda c, *a: c.subscribe(
            [
                (f"{interface}/+/+/+/{topic}", 0)
                for interface in interfaces
                for topic in ("order", "instantActions", "zoneSet", "responses")
            ]
        )
        self.client.on_message = self._on_message
        self.client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
        self.client.loop_start()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        with self._lock:
            self.messages.append((message.topic, orjson.loads(message.payload)))

    def for_robot(self, serial: str, topic: str) -> list[dict[str, Any]]:
        with self._lock:
            return [m for t, m in self.messages if t.endswith(f"/{serial}/{topic}")]

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


@pytest.fixture(scope="package")
def recorder() -> Iterator[Recorder]:
    recorder = Recorder()
    yield recorder
    recorder.close()
    for topic, message in recorder.messages:
        validate_message(topic.rsplit("/", 1)[-1], message["version"], legacy_key_as_actions(message))


def legacy_key_as_actions(message: dict[str, Any]) -> dict[str, Any]:
    """An instant actions message under the 1.1 key (sent to robots that read only that one, README
    "Vehicle compatibility rules") is checked as what it is otherwise: a conformant message."""
    if "instantActions" in message and "actions" not in message:
        return {("actions" if key == "instantActions" else key): value for key, value in message.items()}
    return message


def start_servers(logs: Path, **overrides: str) -> Stack:
    """Bridge, worker, beat and the API against the test database and the test Redis, time compressed;
    `overrides` are more settings (another broker, say)."""
    env = {
        **os.environ,
        **SERVER_ENV,
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
        "FLEET_DB_NAME": connection.settings_dict["NAME"],
        "FLEET_REDIS_URL": settings.REDIS_URL,
        "PYTHONUNBUFFERED": "1",
        **overrides,
    }
    stack = Stack(env=env, logs=logs)
    stack.add("bridge", BRIDGE)
    stack.add("worker", WORKER)
    stack.add("beat", [CELERY, "-A", "fleet", "beat", "--schedule", str(logs / "beat-schedule")])
    stack.add("api", granian_command(ASGI, stack.api_port))  # the streams, on the API's port
    return stack


@pytest.fixture(scope="package")
def stack(
    django_db_setup: None, recorder: Recorder, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Stack]:
    import redis

    redis.Redis.from_url(settings.REDIS_URL).flushdb()
    logs = tmp_path_factory.mktemp("stack-logs")
    stack = start_servers(logs)
    yield stack
    stack.stop()
    print(f"stack logs in {logs}")


@pytest.fixture
def api(api_token: str) -> APIClient:
    return authenticated_client(api_token)


@dataclass
class Simulator:
    process: Process
    names: list[str]


def simulator_command(*specs: str, extra: tuple[str, ...] = ()) -> list[str]:
    """A simulator of robot specs like `"{name},0,0"` whose robots drive fast and report often, on the
    interface (first topic level) the robots created here get (FLEET_VDA5050_INTERFACE_NAME)."""
    fast = ["--tick_period", "0.05", "--speed", "10", "--state_period", "0.5"]
    interface = ["--interface_name", settings.VDA5050_INTERFACE_NAME]
    return [PYTHON, "-m", "simulator", "--robots", *specs, *fast, *interface, *extra]


@pytest.fixture
def simulator(stack: Stack, tmp_path: Path) -> Iterator[Callable[..., Simulator]]:
    """Start a simulator for robot specs like `"{name},0,0"`; stopped at the end of the test."""
    started: list[Process] = []

    def start(*specs: str, extra: tuple[str, ...] = ()) -> Simulator:
        argv = simulator_command(*specs, extra=extra)
        process = Process(
            f"simulator-{len(started)}", argv, stack.env, tmp_path / f"simulator-{len(started)}.log"
        )
        process.start()
        started.append(process)
        return Simulator(process, [spec.split(",")[0] for spec in specs])

    yield start
    for process in started:
        process.stop()


@pytest.fixture
def simulated_robot(
    api: APIClient, simulator: Callable[..., Simulator], unique: Callable[[str], str]
) -> Callable[[str], str]:
    """A robot created through the API and simulated at (0, 0), named uniquely from `base`."""

    def create(base: str) -> str:
        name = unique(base)
        simulator(f"{name},0,0")
        response = api.post("/robot", {"name": name}, format="json")
        assert response.status_code == 200, response.content
        return name

    return create


@pytest.fixture
def unique() -> Callable[[str], str]:
    """Robot and mission names unique to this test run."""
    suffix = uuid.uuid4().hex[:6]
    return lambda base: f"{base}-{suffix}"
