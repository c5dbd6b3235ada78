"""The benchmark's yardstick (issue #42, item 1): server CPU per order beside throughput and latency, the
calibration with round trips to the real PostgreSQL and Redis, and `bench.suite --ab REF`: the suite on
REF's tree and this one in interleaved pairs, each run on a stack of its own started afresh. The suite's
runs here are `tiny` (a few seconds of five robots) on a stack of the test's own (database, ports)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import psycopg
import pytest
import redis
from django.conf import settings
from django.db import connection

from bench import measure, suite
from bench.measure import ProcessSample, Snapshot
from tests.waiting import wait_for

# --- the figures, from given numbers ------------------------------------------------------------------------


def test_cpu_per_order_is_every_server_groups_cpu_over_the_orders_and_scales_to_the_reference_hour() -> None:
    processes = {
        "api": {"cpu_seconds": 1.0},
        "postgres": {"cpu_seconds": 0.5},
        "redis": {"cpu_seconds": 0.5},
        measure.GENERATOR: {"cpu_seconds": 7.0},  # the load, not the server
    }

    figures = measure.cpu_per_order(processes, orders=400, cal_ms=268.0)

    assert figures["server_cpu_seconds"] == 2.0
    assert figures["server_ms"] == 5.0  # 2 s / 400 orders
    assert figures["at_reference_ms"] == 2.5  # a machine twice as slow as at cal 134 scales down
    assert figures["by_group_ms"] == {"api": 2.5, "postgres": 1.25, "redis": 1.25}
    assert measure.cpu_per_order(processes, orders=0, cal_ms=268.0)["server_ms"] is None  # an idle run


def test_a_process_that_ended_is_not_taken_off_a_group_its_parent_is_not_in() -> None:
    """One database's postgres backends without the postmaster: a backend that ended took its CPU to the
    postmaster's children's time, outside the group; it must not count negative."""
    before = Snapshot({"postgres": [20, 21]}, {20: ProcessSample(3.0, 0, 1), 21: ProcessSample(9.0, 0, 1)})
    after = Snapshot({"postgres": [20]}, {20: ProcessSample(3.5, 0, 1)})

    assert measure.usage(before, after, 1.0)["postgres"]["cpu_seconds"] == 0.5


def test_interleaved_order_reverses_the_sides_every_other_round() -> None:
    order = list(measure.interleaved_order(["a", "b"], 3))

    assert order == [(0, "a"), (0, "b"), (1, "b"), (1, "a"), (2, "a"), (2, "b")]


# --- the round trips, against the real services ----------------------------------------------------------


@pytest.mark.django_db
def test_round_trip_probes_make_their_round_trips_to_the_real_postgresql_and_redis() -> None:
    database = connection.settings_dict["NAME"]
    conninfo = f"host=127.0.0.1 user=postgres dbname={database}"
    client = redis.Redis.from_url(settings.REDIS_URL)
    pings_before = _pings(client)
    commits_before = _commits(conninfo, database)

    figures = measure.round_trip_us(conninfo, settings.REDIS_URL, count=200)

    loops = 200 * measure.ROUND_TRIP_REPEATS
    assert 0 < figures["select1_us"] < 100_000 and 0 < figures["redis_ping_us"] < 100_000
    assert _pings(client) - pings_before >= loops  # each PING went to the server
    # each SELECT 1 was a transaction of its own on the server (its backend reports as it ends)
    wait_for(lambda: _commits(conninfo, database) - commits_before >= loops, "the probe's commits counted")
    assert measure.round_trip_us(None, None) == {"select1_us": None, "redis_ping_us": None}


def test_broker_publishes_counts_what_is_pushed_onto_lists_on_the_server() -> None:
    client = redis.Redis.from_url(settings.REDIS_URL)
    key = f"bench-publishes-{os.getpid()}"
    before = measure.broker_publishes(settings.REDIS_URL)
    try:
        for number in range(5):
            client.lpush(key, number)
        after = measure.broker_publishes(settings.REDIS_URL)
    finally:
        client.delete(key)
    assert before is not None and after is not None and after - before >= 5
    assert measure.broker_publishes(None) is None


def _pings(client: redis.Redis) -> int:
    return int(client.info("commandstats").get("cmdstat_ping", {}).get("calls", 0))


def _commits(conninfo: str, database: str) -> int:
    with psycopg.connect(conninfo, autocommit=True) as probe:
        probe.execute("SELECT pg_stat_force_next_flush()")
        row = probe.execute("SELECT xact_commit FROM pg_stat_database WHERE datname = %s", [database])
        return int(row.fetchone()[0])


# --- the suite on a stack of the test's own -----------------------------------------------------------------


@pytest.fixture
def own_stack(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[None]:
    """bench.suite's stack on free ports and a database of the test's own (never `make bench`'s); a decoy
    process whose command line looks like a bridge and a worker of another checkout, which must not count."""
    database = f"{os.environ.get('FLEET_DB_NAME', 'mission_dispatch')}_stack"
    monkeypatch.setattr(suite, "DB_NAME", database)
    for name in ("API_PORT", "BROKER_PORT", "REDIS_PORT"):
        monkeypatch.setattr(suite, name, _free_port())
    monkeypatch.setattr(suite, "BEAT_SCHEDULE", str(tmp_path / "beat-schedule"))
    sleep = "import time; time.sleep(300)"
    decoy = subprocess.Popen([sys.executable, "-c", sleep, "/elsewhere/manage.py mqtt_bridge celery worker"])
    try:
        yield
    finally:
        decoy.kill()
        decoy.wait()
        subprocess.run(["dropdb", "--if-exists", "-h", "127.0.0.1", "-U", "postgres", database], check=False)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _assert_yardstick(result: dict[str, Any]) -> None:
    """The run's per-order CPU and calibration are there and positive, and its CPU is the stack's own."""
    per_order, machine, cpu = result["cpu_per_order"], result["machine"], result["cpu"]
    assert per_order["orders"] > 0 and per_order["server_ms"] > 0 and per_order["at_reference_ms"] > 0
    assert per_order["at_reference_ms"] == pytest.approx(
        per_order["server_ms"] * measure.REFERENCE_CAL_MS / machine["cpu_speed_ms"], rel=1e-3
    )
    assert machine["cpu_speed_ms"] > 0 and machine["select1_us"] > 0 and machine["redis_ping_us"] > 0
    assert result["tasks_per_order"] > 0  # the steps' Celery tasks, counted on the stack's own Redis
    processes = {group: figures["processes"] for group, figures in cpu.items()}
    # granian and its worker; one bridge (not the decoy); the step and notify workers; beat; the stack's
    # Redis, its broker and its database's backends
    assert processes["api"] >= 2 and processes["bridge"] == 1 and processes["workers"] == 2
    assert processes["beat"] == processes["redis"] == processes["broker"] == 1 and processes["postgres"] >= 1
    assert all(cpu[group]["cpu_seconds"] >= 0 for group in cpu)


@pytest.mark.e2e
@pytest.mark.usefixtures("own_stack")
def test_the_suite_prints_and_reports_server_cpu_per_order_with_the_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert suite.main(["--suite", "tiny", "--output", str(tmp_path)]) == 0

    [path] = tmp_path.glob("run-n5-*.json")
    _assert_yardstick(json.loads(path.read_text()))
    printed = capsys.readouterr().out
    assert "=== saturation-n5: " in printed and "server CPU per order" in printed and "cal " in printed
    latest = (tmp_path / "latest.md").read_text()
    assert "server CPU ms/order" in latest and "SELECT 1 µs" in latest


@pytest.mark.e2e
@pytest.mark.usefixtures("own_stack")
def test_ab_runs_the_suite_on_refs_tree_and_this_one_interleaved_and_writes_the_comparison(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert suite.main(["--suite", "tiny", "--ab", "HEAD", "--pairs", "1", "--output", str(tmp_path)]) == 0

    comparison = json.loads((tmp_path / "ab.json").read_text())
    assert comparison["pairs"] == 1 and comparison["order"] == ["a1", "b1"]
    [pair] = comparison["runs"]["saturation-n5"]["pairs"]
    a, b = pair["a"]["cpu_ms_per_order"], pair["b"]["cpu_ms_per_order"]
    assert a > 0 and b > 0 and pair["cpu_ratio"] == pytest.approx(b / a, rel=1e-2)
    assert comparison["runs"]["saturation-n5"]["median_cpu_ratio"] == pair["cpu_ratio"]
    results = sorted((json.loads(p.read_text()) for p in tmp_path.glob("run-n5-*.json")), key=_started)
    assert [result["label"] for result in results] == ["mission-dispatch a", "mission-dispatch b"]
    for result in results:
        _assert_yardstick(result)
    # side a's bridge ran from the temporary worktree of HEAD, side b's from this tree; the worktree is gone
    ref_bridge = results[0]["options"]["process_groups"]["bridge"]
    assert str(suite.ROOT) not in ref_bridge.replace("\\", "")
    assert str(suite.ROOT) in results[1]["options"]["process_groups"]["bridge"].replace("\\", "")
    worktrees = subprocess.run(["git", "worktree", "list"], cwd=suite.ROOT, capture_output=True, text=True)
    assert "md-ab-" not in worktrees.stdout
    printed = capsys.readouterr().out
    assert printed.index("[pair 1, a: HEAD") < printed.index("[pair 1, b: this tree")
    assert "median ratio b / a" in printed and (tmp_path / "ab.md").read_text() in printed


def _started(result: dict[str, Any]) -> str:
    return result["started_at"]
