"""Fixtures shared by the test suite."""

import pytest
from rest_framework.test import APIClient

import missions.services
import robots.services
from access.services import api_token_create

# The name of the token the `api` fixtures authenticate with; writes are recorded as token:<name>.
API_TOKEN_NAME = "tests"


def authenticated_client(token: str) -> APIClient:
    """A client of the REST API that sends `token` as its bearer token."""
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Bearer {token}")
    return client


@pytest.fixture
def api_token(db: None) -> str:
    """A new read-write API token (plaintext), made as `api_token create` makes one."""
    return api_token_create(name=API_TOKEN_NAME)[1]


@pytest.fixture
def api(api_token: str) -> APIClient:
    """A client of the REST API that sends JSON bodies and a read-write token."""
    client = authenticated_client(api_token)
    client.default_format = "json"
    return client


@pytest.fixture
def woken(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Robots the services asked the dispatch engine to step (kit.wake.request_steps), in call order."""
    names: list[str] = []
    monkeypatch.setattr(robots.services, "request_steps", names.extend)
    monkeypatch.setattr(missions.services, "request_steps", names.extend)
    return names
