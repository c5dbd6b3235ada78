"""The API process (granian ASGI, fleet.asgi: REST and the streams) on the test database."""

from collections.abc import Iterator
from pathlib import Path

import pytest
from django.db import connection

from access.services import api_token_create
from tests.granian_server import ASGI, GranianServer, granian_server
from tests.watching import watches

QUEUE_LINES = 1000  # FLEET_WATCH_QUEUE_LINES of the stream server: small, so a slow watcher is soon dropped
KEEPALIVE_SECONDS = 1.0  # FLEET_EVENTS_KEEPALIVE_SECONDS: keepalives come within a test's patience
RETRY_MS = 250  # FLEET_EVENTS_RETRY_SECONDS, as the streams' retry: field says it
API_THREADS = 2  # FLEET_API_THREADS: REST requests' threads, each keeping its database connection
CREDENTIALS_CHECK_SECONDS = 0.5  # FLEET_STREAM_CREDENTIALS_CHECK_SECONDS: a revoked token's stream ends soon


@pytest.fixture
def stream_server(transactional_db: None, tmp_path: Path) -> Iterator[GranianServer]:
    _, token = api_token_create(name="stream-server")
    env = {
        "FLEET_WATCH_QUEUE_LINES": str(QUEUE_LINES),
        "FLEET_WATCH_POLL_SECONDS": "0.05",
        "FLEET_EVENTS_KEEPALIVE_SECONDS": str(KEEPALIVE_SECONDS),
        "FLEET_EVENTS_RETRY_SECONDS": str(RETRY_MS / 1000),
        "FLEET_API_THREADS": str(API_THREADS),
        "FLEET_STREAM_CREDENTIALS_CHECK_SECONDS": str(CREDENTIALS_CHECK_SECONDS),
    }
    with granian_server(ASGI, log=tmp_path / "stream.log", token=token, env=env) as server:
        yield server


def server_connections() -> int:
    """Connections to the test database other than this test's own: the server's."""
    with connection.cursor() as cursor:
        cursor.execute(
            "SELECT count(*) FROM pg_stat_activity WHERE datname = %s AND pid <> pg_backend_pid()",
            [connection.settings_dict["NAME"]],
        )
        return cursor.fetchone()[0]


__all__ = ["watches"]
