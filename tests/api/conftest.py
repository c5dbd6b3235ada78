"""A real API server for the tests that need one: granian serving fleet.wsgi, as in production."""

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import requests
from django.db import connection

from access.services import api_token_create
from tests.private_redis import PrivateRedis, free_port

ROOT = Path(__file__).resolve().parents[2]
START_SECONDS = 60


@dataclass
class ApiServer:
    url: str
    process: subprocess.Popen[bytes]
    log: Path
    token: str  # a read-write API token in the server's database

    @property
    def auth(self) -> dict[str, str]:
        """The header that authenticates a request with `token`."""
        return {"Authorization": f"Bearer {self.token}"}

    def output(self) -> str:
        return self.log.read_text(errors="replace")


@pytest.fixture
def api_server(transactional_db: None, tmp_path: Path) -> Iterator[ApiServer]:
    """granian with one worker process on the test database (so its writes are committed: the test is
    transactional, as is the server's token) and a Redis of its own for the wake-ups it sends (no worker
    takes them)."""
    redis = PrivateRedis(tmp_path).start()
    port = free_port()
    log = tmp_path / "granian.log"
    env = {
        **os.environ,
        "FLEET_DB_NAME": connection.settings_dict["NAME"],
        "FLEET_REDIS_URL": redis.url,
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
    }
    argv = [sys.executable, "-m", "granian", "--interface", "wsgi", "--host", "127.0.0.1"]
    argv += ["--port", str(port), "--workers", "1", "--no-ws", "fleet.wsgi:application"]
    with log.open("ab") as output:
        process = subprocess.Popen(
            argv, cwd=ROOT, env=env, stdout=output, stderr=subprocess.STDOUT, start_new_session=True
        )
    _, token = api_token_create(name="api-server")
    server = ApiServer(url=f"http://127.0.0.1:{port}", process=process, log=log, token=token)
    try:
        _wait_until_healthy(server)
        yield server
    finally:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=30)
        redis.kill()


def _wait_until_healthy(server: ApiServer) -> None:
    deadline = time.monotonic() + START_SECONDS
    while True:
        try:
            if requests.get(f"{server.url}/health", timeout=5).status_code == 200:
                return
        except requests.ConnectionError:
            pass
        if server.process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"the API server did not start:\n{server.output()}")
        time.sleep(0.1)
