"""The public REST API of Mission Dispatch (and of the reference), called from the event loop.

Requests run in a small thread pool, each thread with its own keep-alive ``http.client`` connection, so
the loop never blocks and connections are reused. (``requests`` cost the generator three times the CPU per
request, mostly on proxy and environment look-ups: CPU the server under test then lacks.)
"""

from __future__ import annotations

import asyncio
import http.client
import socket
import threading
import time
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import Any
from urllib.parse import urlencode, urlsplit

import orjson

HTTP_TIMEOUT = 30.0  # s per request
NAMES_PER_QUERY = 50  # robots per GET /robot?names=...


class ApiError(RuntimeError):
    """A request the server answered with an error status."""

    def __init__(self, message: str, status: int, body: str) -> None:
        super().__init__(message)
        self.status = status
        self.body = body


class DispatchApi:
    def __init__(self, base_url: str, concurrency: int, token: str | None = None) -> None:
        self.base_url = base_url.rstrip("/")
        self._auth = {"Authorization": f"Bearer {token}"} if token else {}
        url = urlsplit(self.base_url)
        self._host, self._port, self._root = url.hostname or "127.0.0.1", url.port or 80, url.path
        self._executor = ThreadPoolExecutor(max_workers=concurrency, thread_name_prefix="http")
        self._local = threading.local()
        self.retries = 0  # requests sent twice after a connection error

    async def create_robot(self, name: str) -> None:
        await self._call("POST", "/robot", json={"name": name})

    async def delete_robot(self, name: str) -> None:
        await self._call("DELETE", f"/robot/{name}")

    async def post_mission(self, body: dict[str, Any]) -> float:
        """Returns when (time.monotonic) the request went out: waiting for a free thread does not count."""
        sent_at, _ = await self._call("POST", "/mission", json=body)
        return sent_at

    async def online_robots(self, names: Iterable[str]) -> set[str]:
        """Which of ``names`` the server shows online (status.online)."""
        names = list(names)
        chunks = [names[i : i + NAMES_PER_QUERY] for i in range(0, len(names), NAMES_PER_QUERY)]
        answers = await asyncio.gather(
            *(self._call("GET", "/robot", params={"names": chunk}) for chunk in chunks)
        )
        pages = [page for _, page in answers]
        return {robot["name"] for page in pages for robot in page if robot.get("status", {}).get("online")}

    async def missions(self, **filters: str) -> list[dict[str, Any]]:
        _, missions = await self._call("GET", "/mission", params=filters)
        return missions

    def close(self) -> None:
        self._executor.shutdown(wait=True)

    async def _call(self, method: str, path: str, **kwargs: Any) -> tuple[float, Any]:
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._executor, self._request, method, path, kwargs)

    def _request(self, method: str, path: str, kwargs: dict[str, Any]) -> tuple[float, Any]:
        target = self._root + path
        if kwargs.get("params"):
            target += "?" + urlencode(kwargs["params"], doseq=True)
        body = orjson.dumps(kwargs["json"]) if "json" in kwargs else None
        try:
            sent_at = time.monotonic()
            status, payload = self._exchange(method, target, body)
        except (http.client.HTTPException, ConnectionError):
            # Typically a kept-alive connection the server closed just as it was reused: the request
            # never arrived, so sending it once more, on a new connection, is safe.
            self._local.connection = None
            self.retries += 1
            sent_at = time.monotonic()
            status, payload = self._exchange(method, target, body)
        if status >= 400:
            text = payload.decode(errors="replace")
            raise ApiError(f"{method} {path}: {status} {text[:300]}", status, text)
        return sent_at, orjson.loads(payload)

    def _exchange(self, method: str, target: str, body: bytes | None) -> tuple[int, bytes]:
        connection = getattr(self._local, "connection", None)
        if connection is None:
            connection = http.client.HTTPConnection(self._host, self._port, timeout=HTTP_TIMEOUT)
            connection.connect()
            # As urllib3 does: without it, Nagle's algorithm and delayed ACKs hold small requests back.
            connection.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._local.connection = connection
        headers = {**self._auth, "Content-Type": "application/json"} if body is not None else self._auth
        connection.request(method, target, body=body, headers=headers)
        response = connection.getresponse()
        return response.status, response.read()
