"""A 10-second run of the benchmark against the real server processes (CI's smoke run).

The server is the e2e harness's (bridge, worker, beat with the same environment and time compression)
plus the API (granian) on a free port, all against the test database; they run for this module only, so they
never overlap the e2e session's own processes. Every message on the benchmark robots' topics, theirs
and the server's, must pass the official VDA 5050 2.0.0 schema.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import threading
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
import requests
from django.conf import settings

from bench import report
from bench.fleet import SETTLED_READINGS
from bench.measure import DEFAULT_PROCESS_GROUPS, GENERATOR
from bench.suite import API_NICENESS, api_command
from tests.bench.generator import run_generator
from tests.e2e.conftest import PYTHON, ROOT, Stack, start_servers
from tests.vda5050.schemas import validate_message
from tests.waiting import wait_for
from vda5050.codec import parse_state

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

PREFIX = "uagv/v2/RobotCompany"  # the server's default identity for robots created by name
START_RATE = 5.0  # missions/s in the start phase


@dataclass
class Server:
    """A complete server: API, bridge, worker and beat against the test database."""

    stack: Stack
    base_url: str


@pytest.fixture(scope="module")
def server(django_db_setup: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    logs = tmp_path_factory.mktemp("bench-stack-logs")
    stack = start_servers(logs)
    stack.processes.pop("api").stop()  # replaced by deploy/Procfile's command line, niceness and all
    port = _free_port()
    stack.add("api", api_command(port, workers=1))
    base_url = f"http://127.0.0.1:{port}"
    try:
        wait_for(lambda: _answers(base_url), message=f"the API on {base_url}")
        yield Server(stack, base_url)
    finally:
        stack.stop()
        print(f"bench stack logs in {logs}")


class Capture:
    """Every message on the topics of one run's robots."""

    def __init__(self, serial_prefix: str) -> None:
        self.serial_prefix = serial_prefix
        self.messages: list[tuple[str, str, bytes]] = []  # (serial, topic, payload)
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=f"capture-{uuid.uuid4().hex[:8]}"
        )
        self.client.on_connect = lambda client, *args: client.subscribe(f"{PREFIX}/+/+")
        self.client.on_subscribe = lambda *args: self._subscribed.set()
        self.client.on_message = self._on_message
        self.client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
        self.client.loop_start()
        wait_for(self._subscribed.is_set, message="the capture's subscription")

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        serial, topic = message.topic.split("/")[-2:]
        if serial.startswith(self.serial_prefix):
            with self._lock:
                self.messages.append((serial, topic, message.payload))

    def of(self, topic: str) -> list[dict[str, Any]]:
        """Messages on `topic`, without the empty payloads that clear retained messages at cleanup."""
        with self._lock:
            return [orjson.loads(payload) for _, name, payload in self.messages if name == topic and payload]

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def test_the_api_runs_below_the_dispatch_path_in_cpu_priority(server: Server) -> None:
    """The stack's API (as `deploy/Procfile`'s) waits for the bridge whenever both want a CPU."""
    api, bridge = (server.stack.processes[name].popen.pid for name in ("api", "bridge"))
    bridge_niceness = os.getpriority(os.PRIO_PROCESS, bridge)
    assert os.getpriority(os.PRIO_PROCESS, api) == min(bridge_niceness + API_NICENESS, 19)
    workers = [int(pid) for pid in Path(f"/proc/{api}/task/{api}/children").read_text().split()]
    assert workers, "the API has no worker processes"
    assert {os.getpriority(os.PRIO_PROCESS, pid) for pid in workers} == {os.getpriority(os.PRIO_PROCESS, api)}


def test_ten_second_run_completes_missions_with_valid_messages(
    server: Server, api_token: str, tmp_path: Path
) -> None:
    run_id = uuid.uuid4().hex[:6]
    capture = Capture(f"bench-{run_id}-")
    try:
        run_generator(
            "bench.fleet",
            "--base-url",
            server.base_url,
            "--api-token",
            api_token,
            "--mqtt-host",
            settings.MQTT_HOST,
            "--mqtt-port",
            str(settings.MQTT_PORT),
            "--mqtt-prefix",
            PREFIX,
            "--robots",
            "5",
            "--nodes",
            "3",
            "--start-rate",
            str(START_RATE),
            "--duration",
            "10",
            "--warmup",
            "1",
            "--sample-every",
            "3",
            "--run-id",
            run_id,
            "--output",
            str(tmp_path),
        )
        wait_for(  # the last messages may still be on their way to the capture
            lambda: any(c["connectionState"] == "OFFLINE" for c in capture.of("connection")),
            message="the robots' OFFLINE",
        )
    finally:
        capture.close()

    result = json.loads((tmp_path / f"run-n5-{run_id}.json").read_text())
    markdown = (tmp_path / f"run-n5-{run_id}.md").read_text()
    assert markdown.startswith("## run: 5 robots")
    assert "| step p99 ms |" in markdown
    speed = result["machine"]["cpu_speed_ms"]
    assert speed > 0 and result["machine"]["busy_pct"] > 0
    assert f"| CPU speed at the start (ms of calibration work; lower is faster) | {speed} |" in markdown
    header, _, row = report.summary_markdown([result]).splitlines()[:3]
    cells = dict(zip(header.split(" | "), row.split(" | "), strict=True))
    assert cells["CPU speed ms"] == str(speed)  # the calibration in its column of the summary
    missions = result["missions"]
    assert missions["completed"] > 0
    assert missions["failed"] == 0, missions["failure_reasons"]
    assert missions["abandoned"] == 0
    assert result["errors"]["post_errors"] == result["errors"]["malformed_messages"] == 0
    assert result["errors"]["start_timeouts"] == result["errors"]["mqtt_disconnects"] == 0
    assert result["start_latency_ms"]["count"] == 5
    assert result["settle_seconds"] >= SETTLED_READINGS
    first_orders = {}  # robot -> when the server sent it its first order (epoch s, the server's clock)
    for order in capture.of("order"):
        sent = datetime.fromisoformat(order["timestamp"].replace("Z", "+00:00")).timestamp()
        first_orders[order["serialNumber"]] = min(sent, first_orders.get(order["serialNumber"], sent))
    # Posted at START_RATE, the five first orders span four intervals (all at once, a few milliseconds).
    assert max(first_orders.values()) - min(first_orders.values()) >= 3 / START_RATE
    assert result["step_latency_ms"]["count"] > 0
    assert result["throughput"]["orders_per_second"] > 0
    assert set(result["cpu"]) == {*DEFAULT_PROCESS_GROUPS, GENERATOR}
    series = result["series"]  # 10 s in slices of about 3 s
    assert len(series) == result["drift"]["slices"] == 3
    assert series[-1]["t"] == pytest.approx(result["window_seconds"], abs=0.2)
    assert sum(point["steps"] for point in series) == result["step_latency_ms"]["count"]
    assert set(series[0]["rss_mb"]) == set(result["drift"]["rss_mb"]) == set(result["cpu"])
    assert series[-1]["rss_mb"] == {group: usage["rss_mb"] for group, usage in result["cpu"].items()}
    assert (tmp_path / f"run-n5-{run_id}-series.png").stat().st_size > 0

    states, orders = capture.of("state"), capture.of("order")
    assert len(states) > len(orders) >= missions["completed"] * 3
    for topic in ("state", "connection", "factsheet", "order", "instantActions"):
        for message in capture.of(topic):
            validate_message(topic, "2.0.0", message)
    for state in states:
        parse_state(orjson.dumps(state))
    done = [s for s in states if s["orderId"] and not s["nodeStates"] and s["lastNodeSequenceId"] > 0]
    assert done, "no state reports a finished order"
    assert "ONLINE" in {message["connectionState"] for message in capture.of("connection")}

    summary = subprocess.run(
        [PYTHON, "-m", "bench.report", str(tmp_path / f"run-n5-{run_id}.json"), "--output", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    assert "| run | 5 | 3 | 2 |" in summary.stdout
    assert (tmp_path / "latest.png").stat().st_size > 0


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _answers(base_url: str) -> bool:
    try:
        return requests.get(f"{base_url}/health", timeout=2).status_code == 200
    except requests.RequestException:
        return False
