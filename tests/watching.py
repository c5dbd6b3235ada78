"""A client of the watch streams (GET /robot/watch, GET /mission/watch) for the tests."""

import queue
import socket
import threading
from collections.abc import Iterator
from typing import Any

import orjson
import pytest
import requests

from tests.waiting import WAIT_SECONDS


class Watch:
    """One open watch stream, its lines parsed as they come by a thread of its own."""

    def __init__(self, url: str, headers: dict[str, str], *, read: bool = True) -> None:
        self.response = requests.get(url, headers=headers, stream=True, timeout=(5, 120))
        self.response.raise_for_status()
        self._socket = self.response.raw.connection.sock
        self._lines: queue.Queue[dict[str, Any] | None] = queue.Queue()
        if read:
            self.start_reading()

    def start_reading(self) -> None:
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            for line in self.response.iter_lines():
                self._lines.put(orjson.loads(line))
        except requests.RequestException:
            pass
        self._lines.put(None)

    def next(self, timeout: float = WAIT_SECONDS) -> dict[str, Any] | None:
        """The next line (None once the stream ended)."""
        return self._lines.get(timeout=timeout)

    def take(self, count: int) -> list[dict[str, Any]]:
        return [self.next() for _ in range(count)]

    def quiet(self, seconds: float = 1.0) -> bool:
        """True if no line comes within `seconds`."""
        try:
            line = self._lines.get(timeout=seconds)
        except queue.Empty:
            return True
        self._lines.put(line)
        return False

    def close(self) -> None:
        """Hang up (urllib3 would read the endless body to its end first)."""
        self._socket.shutdown(socket.SHUT_RDWR)
        self.response.close()


@pytest.fixture
def watches() -> Iterator[list[Watch]]:
    """Watches a test opens, closed after it."""
    opened: list[Watch] = []
    yield opened
    for watch in opened:
        watch.close()
