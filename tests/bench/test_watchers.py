"""A few seconds of bench.watchers against the real server processes: a small fleet doing missions, a few
watchers of GET /events and of GET /mission/watch, every transition of every completed mission delivered
to each, the same on each: one watcher checks every object, the others' fingerprints of the missions (no
parsing, as hundreds of watchers are read) must match its."""

from __future__ import annotations

import json
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from django.conf import settings

from tests.bench.generator import run_generator
from tests.e2e.conftest import Stack, start_servers
from tests.granian_server import healthy
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


@pytest.fixture(scope="module")
def stack(django_db_setup: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stack]:
    logs = tmp_path_factory.mktemp("watchers-stack-logs")
    stack = start_servers(logs)
    try:
        wait_for(lambda: healthy(stack.api_url), message="the API")
        yield stack
    finally:
        stack.stop()
        print(f"watchers stack logs in {logs}")


@pytest.mark.parametrize("framing", ["sse", "ndjson"])
def test_a_short_run_delivers_every_transition_to_every_watcher(
    stack: Stack, api_token: str, tmp_path: Path, framing: str
) -> None:
    run_id = uuid.uuid4().hex[:6]
    run_generator(
        "bench.watchers",
        *("--watchers", "3", "--checked-watchers", "1", "--watcher-processes", "1", "--framing", framing),
        *("--base-url", stack.api_url, "--api-token", api_token),
        *("--mqtt-host", settings.MQTT_HOST, "--mqtt-port", str(settings.MQTT_PORT)),
        *("--robots", "3", "--nodes", "2", "--delay", "0.2", "--start-rate", "5"),
        *("--duration", "6", "--warmup", "1", "--sample-every", "3", "--settle-cores", "2"),
        *("--run-id", run_id, "--output", str(tmp_path)),
    )

    result = json.loads((tmp_path / f"watchers-n3-w3-{run_id}.json").read_text())
    watchers = result["watchers"]
    assert (watchers["count"], watchers["checked"], watchers["framing"]) == (3, 1, framing)
    delivery = watchers["delivery"]
    assert delivery["missions_completed"] >= result["missions"]["completed_in_window"] > 0
    assert delivery["missions_without_every_transition"] == 0
    # Every watcher read from the run's first mission to the end-of-run one the same bytes as the checked one.
    assert delivery["watchers_to_the_end"] == 3 and watchers["drain_seconds"] is not None
    assert delivery["bytes_digested"] > 500 * delivery["missions_completed"]
    assert delivery["watchers_that_read_otherwise"] == 0
    assert watchers["errors"] == 0, watchers["error_samples"]
    # RUNNING and COMPLETED of each completed mission, on the checked watcher (and of missions cut short).
    assert watchers["delivery_latency_ms_whole_run"]["count"] >= 2 * delivery["missions_completed"]
    # Those that happened in the measurement window: some, not all.
    assert 0 < watchers["delivery_latency_ms"]["count"] < watchers["delivery_latency_ms_whole_run"]["count"]
    assert watchers["delivery_latency_ms"]["p99"] < 60_000
    assert watchers["rest_get_robot_ms"]["count"] > 0
    assert "api" in result["drift"]["rss_mb"]
    markdown = (tmp_path / f"watchers-n3-w3-{run_id}.md").read_text()
    assert markdown.startswith(f"## watchers: 3 {framing} watchers (1 checked), 3 robots")
