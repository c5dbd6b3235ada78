"""`bench.fleet --unbound` (issue 41): missions posted without a robot to a fleet spread over one map; the
run reports when each was bound, its first order, and the assignment's total distance against the optimum.
A few seconds of five robots on a stack of the test's own (bench.suite's `tiny-unbound`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench import suite
from tests.bench.test_yardstick import own_stack  # noqa: F401 (the fixture)


@pytest.mark.e2e
@pytest.mark.usefixtures("own_stack")
def test_an_unbound_run_binds_every_mission_and_reports_latency_and_distance(tmp_path: Path) -> None:
    assert suite.main(["--suite", "tiny-unbound", "--output", str(tmp_path)]) == 0

    [path] = tmp_path.glob("run-n5-*.json")
    result = json.loads(path.read_text())
    figures = result["assignment"]
    assert figures["missions"] == figures["bound"] == figures["reached_a_robot"] == 5
    assert figures["bind_latency_ms"]["count"] == 5 and figures["bind_latency_ms"]["p99"] is not None
    assert figures["first_order_latency_ms"]["p50"] > 0
    assert figures["last_post_to_last_binding_ms"] is not None
    assert figures["first_orders_per_second"] > 0
    assert 0 < figures["optimal_distance_m"] <= figures["total_distance_m"] + 1e-6
    assert result["throughput"]["orders_per_second"] > 0 and result["errors"]["post_errors"] == 0
    assert result["cpu_per_order"]["server_ms"] > 0
