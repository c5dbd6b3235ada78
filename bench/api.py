"""The public REST API of Mission Dispatch (and of the reference), called from the event loop.

Requests run in a small thread pool, each thread with its own keep-alive ``requests.Session``, so the
loop never blocks and connections are reused.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import requests

HTTP_TIMEOUT = 30.0  # s per request
NAMES_PER_QUERY = 50  # robots per GET /robot?names=...


class ApiError(RuntimeError):
    """A request the server answered with an error status."""

    def __init__(self, message: str, status: int, body: str) -> None:
        super().__init__(message)
        self.status = status
        self.body = body


class DispatchApi:
    def __init__(self, base_url: str, concurrency: int) -> None:
        self.base_url = base_url.rstrip("/")
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
        session = getattr(self._local, "session", None)
        if session is None:
            session = self._local.session = requests.Session()
        try:
            sent_at = time.monotonic()
            response = session.request(method, self.base_url + path, timeout=HTTP_TIMEOUT, **kwargs)
        except requests.ConnectionError:
            # Typically a kept-alive connection the server closed just as it was reused: the request
            # never arrived, so sending it once more is safe.
            self.retries += 1
            sent_at = time.monotonic()
            response = session.request(method, self.base_url + path, timeout=HTTP_TIMEOUT, **kwargs)
        if response.status_code >= 400:
            body = response.text
            raise ApiError(
                f"{method} {path}: {response.status_code} {body[:300]}", response.status_code, body
            )
        return sent_at, response.json()
