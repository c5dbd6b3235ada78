"""bench.rest_cpu's measurement against two real API servers (granian, the test database): each side's
meter counts its own server's processes, workers included, and only them."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from django.conf import settings
from django.db import connection

from access.services import api_token_create
from bench.api_layout import served
from bench.measure import usage
from bench.rest_cpu import cpu_meter, request_round
from bench.suite import api_command
from missions.models import Mission
from tests.e2e.conftest import ROOT
from tests.server_env import SERVER_ENV
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_each_sides_cpu_is_its_own_servers(tmp_path: Path) -> None:
    _, token = api_token_create(name="rest-cpu-test")
    env = {
        **os.environ,
        **SERVER_ENV,
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
        "FLEET_DB_NAME": connection.settings_dict["NAME"],
        "FLEET_REDIS_URL": settings.REDIS_URL,
    }
    headers = {"Authorization": f"Bearer {token}"}
    with (
        served(api_command, env, tmp_path / "a.log", cwd=ROOT) as a,
        served(api_command, env, tmp_path / "b.log", cwd=ROOT) as b,
    ):
        meter = cpu_meter({"a": a, "b": b})
        # granian and its two workers each (GET /health answered once one worker was up; one starting
        # during the round would count its start-up)
        wait_for(
            lambda: [len(meter.snapshot().members[side]) for side in ("a", "b")] == [3, 3], "the workers"
        )
        for side, server in (("a", a), ("b", b)):  # as rest_cpu warms them up: both past their first requests
            request_round(
                server.url, headers, clients=2, requests_per_client=10, tag=f"warm-{side}", get=False
            )
        before = meter.snapshot()
        request_round(a.url, headers, clients=2, requests_per_client=20, tag="t", get=False)
        spent = usage(before, meter.snapshot(), 1.0)
    assert Mission.objects.filter(name__startswith="rest-cpu-t-").count() == 40  # the round's
    assert spent["a"]["cpu_seconds"] > 0.02  # 40 POSTs cost the server that received them
    assert spent["b"]["cpu_seconds"] < spent["a"]["cpu_seconds"] / 4  # the idle one hardly anything
