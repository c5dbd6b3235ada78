"""Clients of the streams for the tests: the watch streams (GET /robot/watch, GET /mission/watch, NDJSON)
and GET /events (server-sent events), each read by a thread of its own as it comes."""

import queue
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import orjson
import pytest
import requests

from tests.waiting import WAIT_SECONDS


class Stream:
    """One open stream; its parsed messages (`_parse`) wait in a queue for the test."""

    def __init__(self, url: str, headers: dict[str, str], *, read: bool = True) -> None:
        self.response = requests.get(url, headers=headers, stream=True, timeout=(5, 120))
        self.response.raise_for_status()
        self._socket = self.response.raw.connection.sock
        self._messages: queue.Queue[Any] = queue.Queue()
        if read:
            self.start_reading()

    def start_reading(self) -> None:
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            for message in self._parse():
                self._messages.put(message)
        except (requests.RequestException, OSError, AttributeError):
            pass  # the server ended the stream, or the test hung up (http.client then has no file left)
        self._messages.put(None)

    def _parse(self) -> Iterator[Any]:
        raise NotImplementedError

    def next(self, timeout: float = WAIT_SECONDS) -> Any:
        """The next message (None once the stream ended)."""
        return self._messages.get(timeout=timeout)

    def take(self, count: int) -> list[Any]:
        return [self.next() for _ in range(count)]

    def quiet(self, seconds: float = 1.0) -> bool:
        """True if no message comes within `seconds`."""
        try:
            message = self._messages.get(timeout=seconds)
        except queue.Empty:
            return True
        self._messages.put(message)
        return False

    def close(self) -> None:
        """Hang up (urllib3 would read the endless body to its end first); once is enough."""
        if self._socket.fileno() != -1:
            self._socket.shutdown(socket.SHUT_RDWR)
        self.response.close()


class Watch(Stream):
    """A watch stream: each line a JSON object."""

    def _parse(self) -> Iterator[dict[str, Any]]:
        for line in self.response.iter_lines():
            yield orjson.loads(line)


@dataclass
class Event:
    """One block of an event stream: an event (`event`, `data` parsed) or, without data, a comment's."""

    event: str | None = None
    data: Any = None
    id: str | None = None  # None: no id line (the client's last event id stays as it was)
    retry: int | None = None
    comments: list[str] = field(default_factory=list)


class Events(Stream):
    """GET /events, parsed as the WHATWG event stream format says (what EventSource does)."""

    def _parse(self) -> Iterator[Event]:
        block, data = Event(), []
        for raw in self.response.iter_lines(delimiter=b"\n"):
            line = raw.decode()
            if not line:
                if data or block.id is not None or block.retry is not None or block.comments:
                    block.data = orjson.loads("\n".join(data)) if data else None
                    yield block
                block, data = Event(), []
            elif line.startswith(":"):
                block.comments.append(line[1:].strip())
            else:
                name, _, value = line.partition(":")
                value = value.removeprefix(" ")
                if name == "data":
                    data.append(value)
                elif name == "event":
                    block.event = value
                elif name == "id":
                    block.id = value
                elif name == "retry":
                    block.retry = int(value)

    def next_event(self, timeout: float = WAIT_SECONDS) -> Event | None:
        """The next block that is an event (a keepalive or `retry` is skipped); None once the stream ended."""
        while (block := self.next(timeout)) is not None and block.event is None:
            pass
        return block

    def events(self, count: int) -> list[Event]:
        return [self.next_event() for _ in range(count)]

    def quiet(self, seconds: float = 1.0) -> bool:
        """True if no event (keepalives aside) comes within `seconds`."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                block = self._messages.get(timeout=left)
            except queue.Empty:
                return True
            if block is None or block.event is not None:
                return False
        return True


@pytest.fixture
def watches() -> Iterator[list[Stream]]:
    """Streams a test opens, closed after it."""
    opened: list[Stream] = []
    yield opened
    for watch in opened:
        watch.close()
