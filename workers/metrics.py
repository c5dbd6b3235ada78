"""Telemetry: counters kept in Redis so every process (API, bridges, workers, beat) adds to the same numbers.

`/metrics` renders them, plus gauges read from PostgreSQL, in the Prometheus text format. Another telemetry
system plugs in through `TELEMETRY_SENDER` (a dotted path to a callable taking `(event, fields)`), which is
called for every counted event.
"""

import bisect
import logging
from collections.abc import Callable, Iterator
from functools import cache
from typing import Any

import redis
from django.conf import settings
from django.db.models import Count
from django.http import HttpResponse
from django.utils.module_loading import import_string
from drf_spectacular.utils import extend_schema
from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily
from prometheus_client.registry import Collector
from rest_framework.negotiation import BaseContentNegotiation
from rest_framework.parsers import BaseParser
from rest_framework.renderers import BaseRenderer
from rest_framework.request import Request
from rest_framework.views import APIView

from robots import livestate

logger = logging.getLogger(__name__)

COUNTERS = f"{livestate.PREFIX}:metrics:counters"
STEP_LATENCY = f"{livestate.PREFIX}:metrics:step-latency"
# Seconds from the robot's state message (or the API call) to the end of the step that answered it.
LATENCY_BUCKETS = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)

MESSAGES_IN = "messages_in"  # labels: topic
MESSAGES_INVALID = "messages_invalid"  # labels: topic, reason (workers.bridge.gate.Drop): dropped unread
MESSAGES_IGNORED = "messages_ignored"  # labels: topic, reason (replayed, stale): read, older than known
MESSAGES_OUT = "messages_out"  # labels: topic
ORDER_REJECTIONS = "order_rejections"
MISSIONS_FINISHED = "missions_finished"  # labels: state, failure_category
STATUS_WRITES_FAILED = "status_writes_failed"  # robot status the database refused (bridge flush)


def _field(name: str, labels: dict[str, str]) -> str:
    return name + "".join(f"|{key}={value}" for key, value in sorted(labels.items()))


def count(name: str, by: int = 1, pipe: redis.client.Pipeline | None = None, **labels: str) -> None:
    """Add `by` to a counter; pass `pipe` to batch it with other Redis commands."""
    if by:
        (pipe or livestate.client()).hincrby(COUNTERS, _field(name, labels), by)
        _send(name, {"by": by, **labels})


def observe_step_latency(seconds: float, pipe: redis.client.Pipeline | None = None) -> None:
    target = pipe or livestate.client()
    target.hincrby(STEP_LATENCY, str(bisect.bisect_left(LATENCY_BUCKETS, seconds)), 1)
    target.hincrbyfloat(STEP_LATENCY, "sum", seconds)


@cache
def _sender() -> Callable[[str, dict[str, Any]], None] | None:
    path = getattr(settings, "TELEMETRY_SENDER", "")
    return import_string(path) if path else None


def _send(event: str, fields: dict[str, Any]) -> None:
    sender = _sender()
    if sender is None:
        return
    try:
        sender(event, fields)
    except Exception:  # a broken telemetry sink must never break dispatch
        logger.exception("telemetry sender failed for %s", event)


class FleetCollector(Collector):
    """Prometheus collector reading the shared counters from Redis and fleet gauges from PostgreSQL."""

    def collect(self) -> Iterator[Any]:
        yield from self._counters()
        yield self._latency()
        yield from self._gauges()

    def _counters(self) -> Iterator[CounterMetricFamily]:
        families: dict[str, CounterMetricFamily] = {}
        for raw_field, raw_value in livestate.client().hgetall(COUNTERS).items():
            name, *pairs = raw_field.decode().split("|")
            labels = dict(pair.split("=", 1) for pair in pairs)
            family = families.get(name)
            if family is None:
                family = families[name] = CounterMetricFamily(
                    f"fleet_{name}", name.replace("_", " "), labels=sorted(labels)
                )
            family.add_metric([labels[key] for key in sorted(labels)], int(raw_value))
        yield from families.values()

    def _latency(self) -> HistogramMetricFamily:
        raw = {key.decode(): value for key, value in livestate.client().hgetall(STEP_LATENCY).items()}
        cumulative, buckets = 0, []
        for index, bound in enumerate((*LATENCY_BUCKETS, float("inf"))):
            cumulative += int(raw.get(str(index), 0))
            buckets.append((str(bound) if bound != float("inf") else "+Inf", cumulative))
        return HistogramMetricFamily(
            "fleet_step_latency_seconds",
            "Robot state (or API call) to the end of the dispatch step that handled it",
            buckets=buckets,
            sum_value=float(raw.get("sum", 0.0)),
        )

    def _gauges(self) -> Iterator[GaugeMetricFamily]:
        from missions.models import Mission
        from robots.models import Robot

        online = GaugeMetricFamily("fleet_robots_online", "Robots online", labels=["online"])
        for row in Robot.objects.values("online").annotate(n=Count("name")):
            online.add_metric([str(row["online"]).lower()], row["n"])
        by_state = GaugeMetricFamily("fleet_robots", "Robots by state", labels=["state"])
        for row in Robot.objects.values("state").annotate(n=Count("name")):
            by_state.add_metric([row["state"]], row["n"])
        missions = GaugeMetricFamily(
            "fleet_missions", "Missions by state and failure category", labels=["state", "failure_category"]
        )
        for row in Mission.objects.values("state", "failure_category").annotate(n=Count("name")):
            missions.add_metric([row["state"], row["failure_category"] or ""], row["n"])
        yield from (online, by_state, missions)


class FirstRendererNegotiation(BaseContentNegotiation):
    """Whatever the scraper accepts: the metrics are text, and a refusal is the API's JSON."""

    def select_renderer(
        self, request: Request, renderers: list[BaseRenderer], format_suffix: str | None = None
    ) -> tuple[BaseRenderer, str]:
        return renderers[0], renderers[0].media_type

    def select_parser(self, request: Request, parsers: list[BaseParser]) -> BaseParser | None:
        return parsers[0] if parsers else None


@extend_schema(exclude=True)
class MetricsView(APIView):
    """GET /metrics in the Prometheus text format; it needs a token like the API (Prometheus sends one with
    `authorization: {credentials_file: ...}`)."""

    content_negotiation_class = FirstRendererNegotiation

    def get(self, request: Request) -> HttpResponse:
        registry = CollectorRegistry()
        registry.register(FleetCollector())
        return HttpResponse(generate_latest(registry), content_type=CONTENT_TYPE_LATEST)
