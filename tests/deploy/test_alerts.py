"""deploy/prometheus/alerts.yaml: promtool accepts it, and every metric and label value its rules use is one
that GET /metrics renders (a renamed metric would silently never fire)."""

import re
import subprocess

import pytest
import yaml

from dispatch.vocabulary import MissionState
from robots import livestate
from tests.deploy.layout import DEPLOY, tool
from tests.factories import MissionFactory, RobotFactory
from workers import metrics

ALERTS = DEPLOY / "prometheus" / "alerts.yaml"
RULES = [rule for group in yaml.safe_load(ALERTS.read_text())["groups"] for rule in group["rules"]]
# Series Prometheus makes itself, not our /metrics.
PROMETHEUS_SERIES = {"up"}
SERIES = re.compile(r"\b([a-z_]+)(?:\{([^}]*)\})?\s*(?:\[|\)|>|==|/|\n|$)")


def used_series() -> dict[str, set[str]]:
    """Metric name -> the label matchers the rules give it (`name="value"`)."""
    found: dict[str, set[str]] = {}
    for rule in RULES:
        for name, matchers in SERIES.findall(rule["expr"]):
            if name.startswith("fleet_") or name in PROMETHEUS_SERIES:
                found.setdefault(name, set()).update(m.strip() for m in matchers.split(",") if m.strip())
    return found


def test_promtool_accepts_the_rules():
    promtool = tool("promtool", "apt-get install prometheus (Debian's package has promtool)")
    done = subprocess.run(
        [promtool, "check", "rules", str(ALERTS)], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_every_rule_is_complete():
    names = [rule["alert"] for rule in RULES]
    assert len(names) == len(set(names))
    for rule in RULES:
        assert rule["labels"]["severity"] in {"warning", "critical"}
        assert rule["annotations"]["summary"]


@pytest.fixture
def clean_metrics():
    livestate.client().delete(metrics.COUNTERS, metrics.STEP_LATENCY)
    yield
    livestate.client().delete(metrics.COUNTERS, metrics.STEP_LATENCY)


@pytest.mark.django_db
def test_every_metric_the_rules_use_is_rendered(clean_metrics, client, api_token):
    # One event of every counter, as the bridges and workers count them; robots online and offline; a
    # running mission.
    metrics.count(metrics.MESSAGES_IN, topic="state")
    metrics.count(metrics.MESSAGES_INVALID, topic="state", reason="schema")
    metrics.count(metrics.MESSAGES_IGNORED, topic="state", reason="stale")
    metrics.count(metrics.MESSAGES_OUT, topic="order")
    metrics.count(metrics.ORDER_REJECTIONS)
    metrics.count(metrics.MISSIONS_FINISHED, state=MissionState.FAILED, failure_category="TIMEOUT")
    metrics.count(metrics.STATUS_WRITES_FAILED)
    metrics.observe_step_latency(0.01)
    MissionFactory(robot=RobotFactory(online=True), running=True)
    RobotFactory(online=False)
    response = client.get("/metrics", headers={"Authorization": f"Bearer {api_token}"})
    assert response.status_code == 200
    rendered = response.content.decode()

    used = used_series()
    assert {
        "fleet_step_latency_seconds_bucket",
        "fleet_missions_finished_total",
        "fleet_robots_online",
    } <= set(used)
    for name, matchers in used.items():
        if name in PROMETHEUS_SERIES:
            continue
        assert re.search(rf"^{name}[{{ ]", rendered, re.MULTILINE), name
        for matcher in matchers:
            label, value = matcher.split("=", 1)
            assert f"{label}={value}" in rendered, matcher
