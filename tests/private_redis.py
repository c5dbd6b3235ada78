"""A Redis server of a test's own, on a free port: a test may stop and start it, never the machine's."""

import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Self

import redis
from django.conf import settings

from robots import livestate


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def redis_server_command(port: int, directory: Path) -> list[str]:
    """A Redis server on 127.0.0.1:`port` that keeps nothing on disk (as the machine's)."""
    return [
        "redis-server",
        "--port",
        str(port),
        "--bind",
        "127.0.0.1",
        "--save",
        "",
        "--appendonly",
        "no",
        "--dir",
        str(directory),
        "--protected-mode",
        "no",
    ]


class PrivateRedis:
    """`redis-server` on 127.0.0.1:`port`, keeping nothing on disk, started and killed by the test."""

    def __init__(self, directory: Path) -> None:
        self.port = free_port()
        self.directory = directory
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> Self:
        self.process = subprocess.Popen(
            redis_server_command(self.port, self.directory), stdout=subprocess.DEVNULL, start_new_session=True
        )
        client = self.client()
        deadline = time.monotonic() + 10
        while True:
            try:
                client.ping()
                return self
            except redis.ConnectionError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.02)

    def client(self) -> redis.Redis:
        return redis.Redis.from_url(self.url)

    def kill(self) -> None:
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=10)
            self.process = None


@contextmanager
def live_state_in(url: str) -> Iterator[None]:
    """This process's live state (`robots.livestate`) and step requests in the Redis at `url`."""
    before = settings.REDIS_URL

    def switch(to: str) -> None:
        settings.REDIS_URL = to
        livestate._cached_client.cache_clear()  # a new pool: every thread makes a new connection to it

    switch(url)
    try:
        yield
    finally:
        switch(before)
