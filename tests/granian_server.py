"""Real granian servers for the tests that need one, as deploy/Procfile runs the API (ASGI: REST and the
streams), on the test database (so their writes are committed: such tests are transactional)."""

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import requests
from django.db import connection

from tests.private_redis import free_port

ROOT = Path(__file__).resolve().parents[1]
START_SECONDS = 60
ASGI = ("asginl", "fleet.asgi:application")  # no lifespan: Django has none


@dataclass
class GranianServer:
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


@contextmanager
def granian_server(
    interface: tuple[str, str], *, log: Path, token: str, env: dict[str, str]
) -> Iterator[GranianServer]:
    """granian serving `interface` with one worker process, `env` added to the test's environment."""
    port = free_port()
    environment = {
        **os.environ,
        "FLEET_DB_NAME": connection.settings_dict["NAME"],
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
        **env,
    }
    with log.open("ab") as output:
        process = subprocess.Popen(
            granian_command(interface, port),
            cwd=ROOT,
            env=environment,
            stdout=output,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    server = GranianServer(url=f"http://127.0.0.1:{port}", process=process, log=log, token=token)
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


def granian_command(interface: tuple[str, str], port: int) -> list[str]:
    """granian serving `interface` on `port` with one worker process."""
    kind, app = interface
    argv = [sys.executable, "-m", "granian", "--interface", kind, "--host", "127.0.0.1"]
    return [*argv, "--port", str(port), "--workers", "1", "--no-ws", app]


def healthy(url: str) -> bool:
    """True if the server at `url` answers GET /health."""
    try:
        return requests.get(f"{url}/health", timeout=5).status_code == 200
    except requests.ConnectionError:
        return False


def _wait_until_healthy(server: GranianServer) -> None:
    deadline = time.monotonic() + START_SECONDS
    while not healthy(server.url):
        if server.process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"the server did not start:\n{server.output()}")
        time.sleep(0.1)
