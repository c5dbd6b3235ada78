"""bench.celery_worker's measurement against real Celery workers on the test Redis: each configuration's
tasks run on its own worker, every one of them, and its CPU is that worker's."""

from __future__ import annotations

from pathlib import Path

import pytest
from django.conf import settings
from django.db import connection

from bench.celery_worker import ROOT, measure
from tests.server_env import SERVER_ENV

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_each_configuration_runs_every_task_on_its_own_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name, value in {
        **SERVER_ENV,
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
        "FLEET_DB_NAME": connection.settings_dict["NAME"],
        "FLEET_REDIS_URL": settings.REDIS_URL,
    }.items():
        monkeypatch.setenv(name, value)
    configurations = {"threads": ("--pool threads --concurrency 4", ROOT), "solo": ("--pool solo", ROOT)}

    figures = measure(configurations, rounds=2, tasks=60, wait_ms=1.0, logs=tmp_path)

    for name in configurations:
        assert len(figures[name]["cpu"]) == len(figures[name]["wall"]) == 2  # each round waited for all 60
        assert all(cpu > 0 for cpu in figures[name]["cpu"])  # its worker's CPU, counted
    assert min(figures["solo"]["wall"]) >= 1.0  # one task at a time, each waiting 1 ms
