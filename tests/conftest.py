"""Fixtures shared by the test suite: API clients and tokens, a real API server, robots for the bridge and
the step, a bridge that never connects to MQTT."""

import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from rest_framework.test import APIClient

import missions.services
import robots.services
from access.services import api_token_create
from robots import livestate
from robots.models import InstantAction, Robot
from robots.services import robot_create
from tests.factories import TEST_ACTOR
from tests.granian_server import ASGI, GranianServer, granian_server
from tests.private_redis import PrivateRedis
from vda5050.models import ActionStatus
from workers import tuning
from workers.bridge.loop import Bridge

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


@pytest.fixture
def api_server(transactional_db: None, tmp_path: Path) -> Iterator[GranianServer]:
    """granian with one worker process on the test database (so its writes are committed: the test is
    transactional, as is the server's token) and a Redis of its own for the wake-ups it sends (no worker
    takes them)."""
    redis = PrivateRedis(tmp_path).start()
    _, token = api_token_create(name="api-server")
    try:
        with granian_server(
            ASGI, log=tmp_path / "granian.log", token=token, env={"FLEET_REDIS_URL": redis.url}
        ) as server:
            yield server
    finally:
        redis.kill()


@pytest.fixture
def make_robot(db: None) -> Iterator[Callable[..., Robot]]:
    """Creates robots (through the service) named uniquely for this test; forgets their live state after."""
    names: list[str] = []

    def make(prefix: str = "bridge", **spec: Any) -> Robot:
        robot = robot_create(
            actor=TEST_ACTOR, name=f"{prefix}-{uuid.uuid4().hex[:10]}", prefix=None, spec=spec
        )
        names.append(robot.name)
        return robot

    yield make
    for name in names:
        livestate.forget(name)
        livestate.client().delete(livestate.step_marker_key(name))


@pytest.fixture
def bridge(monkeypatch: pytest.MonkeyPatch) -> Bridge:
    """A bridge that only ever handles what a test hands it: run_forever (and so MQTT) is never called.
    It queues its step requests at once, as a bridge whose workers keep up does: no worker takes the tasks
    here, so every request after the first would find a backlog and be held (`HeldSteps`, tested apart)."""
    monkeypatch.setattr(tuning, "STEP_HOLD_SECONDS", 0.0)
    return Bridge()


@pytest.fixture
def robot(make_robot: Callable[..., Robot], bridge: Bridge) -> Robot:
    """A robot the bridge knows, whose creation-time factsheet request has been answered."""
    created = make_robot()
    InstantAction.objects.filter(robot=created).update(status=ActionStatus.FINISHED.value)
    bridge.directory.reload()
    return created
