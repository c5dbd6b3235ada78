"""Telemetry: shared counters in Redis, the Prometheus rendering, and the hook for another sender."""

from collections.abc import Iterator
from typing import Any

import pytest
from django.test import override_settings

from robots import livestate
from workers import metrics

SENT: list[tuple[str, dict[str, Any]]] = []


def record(event: str, fields: dict[str, Any]) -> None:
    SENT.append((event, fields))


def explode(event: str, fields: dict[str, Any]) -> None:
    raise RuntimeError("telemetry sink down")


@pytest.fixture
def clean_metrics() -> Iterator[None]:
    livestate.client().delete(metrics.COUNTERS, metrics.STEP_LATENCY)
    metrics._sender.cache_clear()
    SENT.clear()
    yield
    livestate.client().delete(metrics.COUNTERS, metrics.STEP_LATENCY)
    metrics._sender.cache_clear()


def test_counted_events_reach_the_configured_telemetry_sender(clean_metrics: None) -> None:
    with override_settings(TELEMETRY_SENDER="tests.workers.test_metrics.record"):
        metrics.count(metrics.MISSIONS_FINISHED, state="FAILED", failure_category="TIMEOUT")
    assert SENT == [(metrics.MISSIONS_FINISHED, {"by": 1, "state": "FAILED", "failure_category": "TIMEOUT"})]


def test_a_failing_telemetry_sender_does_not_break_counting(clean_metrics: None) -> None:
    with override_settings(TELEMETRY_SENDER="tests.workers.test_metrics.explode"):
        metrics.count(metrics.ORDER_REJECTIONS)
    assert livestate.client().hget(metrics.COUNTERS, metrics.ORDER_REJECTIONS) == b"1"


PROMETHEUS_ACCEPT = (
    "application/openmetrics-text;version=1.0.0;escaping=underscores;q=0.5,"
    "application/openmetrics-text;version=0.0.1;q=0.4,text/plain;version=0.0.4;q=0.3"
)


@pytest.mark.django_db
def test_metrics_view_renders_counters_latency_and_gauges(clean_metrics: None, client, api_token) -> None:
    metrics.count(metrics.MESSAGES_IN, by=3, topic="state")
    metrics.observe_step_latency(0.015)
    metrics.observe_step_latency(3.0)
    # As Prometheus scrapes: its bearer token, and an Accept header that names no JSON.
    response = client.get(
        "/metrics", headers={"Authorization": f"Bearer {api_token}", "Accept": PROMETHEUS_ACCEPT}
    )
    assert response.status_code == 200
    assert response["Content-Type"].startswith("text/plain")
    text = response.content.decode()
    assert 'fleet_messages_in_total{topic="state"} 3.0' in text
    assert 'fleet_step_latency_seconds_bucket{le="0.02"} 1.0' in text
    assert 'fleet_step_latency_seconds_bucket{le="+Inf"} 2.0' in text
    assert "fleet_step_latency_seconds_sum 3.015" in text
