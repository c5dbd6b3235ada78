"""The stream process (granian ASGI, fleet.asgi) on the test database."""

from collections.abc import Iterator
from pathlib import Path

import pytest

from access.services import api_token_create
from tests.granian_server import ASGI, GranianServer, granian_server
from tests.watching import watches

QUEUE_LINES = 1000  # FLEET_WATCH_QUEUE_LINES of the stream server: small, so a slow watcher is soon dropped


@pytest.fixture
def stream_server(transactional_db: None, tmp_path: Path) -> Iterator[GranianServer]:
    _, token = api_token_create(name="stream-server")
    env = {"FLEET_WATCH_QUEUE_LINES": str(QUEUE_LINES), "FLEET_WATCH_POLL_SECONDS": "0.05"}
    with granian_server(ASGI, log=tmp_path / "stream.log", token=token, env=env) as server:
        yield server


__all__ = ["watches"]
