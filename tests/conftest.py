"""Fixtures shared by the test suite."""

import pytest
from rest_framework.test import APIClient

import missions.services
import robots.services


@pytest.fixture
def api() -> APIClient:
    """A client of the REST API that sends JSON bodies."""
    client = APIClient()
    client.default_format = "json"
    return client


@pytest.fixture
def woken(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Robots the services asked the dispatch engine to step (fleet.wake.wake_robot), in call order."""
    names: list[str] = []
    monkeypatch.setattr(robots.services, "wake_robot", names.append)
    monkeypatch.setattr(missions.services, "wake_robot", names.append)
    return names
