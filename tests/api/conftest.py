"""A real API server for the tests that need one: granian serving fleet.asgi, as in production."""

from collections.abc import Iterator
from pathlib import Path

import pytest

from access.services import api_token_create
from tests.granian_server import ASGI, GranianServer, granian_server
from tests.private_redis import PrivateRedis


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
