"""The MCP server on the API's port: Streamable HTTP at /mcp (`fleet.asgi` hands it those requests), with
the API's credentials.

Every request is authenticated as a REST request is (`BearerTokenAuthentication`: a usable token, or
nobody when FLEET_API_AUTH is off); no or a bad token is the API's 401. The server is stateless (no MCP
session outlives its request), so a revoked token is refused at its next request and any worker process
answers any request. The tools' Django work runs on the API's request threads (FLEET_API_THREADS), one
borrowed per piece of work, as a REST request borrows one.
"""

import asyncio
import contextvars
import json
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Protocol, TypeVar

from django.conf import settings
from django.db import close_old_connections
from mcp.types import ToolAnnotations
from rest_framework.exceptions import AuthenticationFailed

from access.authentication import BearerTokenAuthentication
from access.choices import ANONYMOUS, token_actor
from access.permissions import NOT_AUTHENTICATED
from agents.tools import CALL, SERVER

T = TypeVar("T")
Scope = dict[str, Any]

MCP_PATHS = frozenset({"/mcp", "/mcp/"})


class Threads(Protocol):
    """The API's request threads (`fleet.asgi.RequestThreads`)."""

    async def borrow(self) -> ThreadPoolExecutor: ...

    def give_back(self, thread: ThreadPoolExecutor) -> None: ...


@dataclass(frozen=True)
class Caller:
    """Who calls: `actor` as write records name it; `name` the token's (None in open mode)."""

    actor: str
    name: str | None
    read_only: bool


@dataclass(frozen=True)
class Call:
    """What a tool needs of its request: who calls, and a way to run Django work on a request thread."""

    caller: Caller
    run: Callable[[Callable[[], T]], Awaitable[T]]

    def may_call(self, annotations: ToolAnnotations | None) -> bool:
        """A read-only token may call the reading tools only."""
        return not self.caller.read_only or bool(annotations and annotations.readOnlyHint)


class McpEndpoint:
    """The ASGI app of /mcp: authenticate, then the SDK's Streamable HTTP transport (stateless, JSON
    responses), started in the server's event loop at the first request (granian runs the API without
    ASGI lifespan)."""

    def __init__(self, threads: Threads) -> None:
        self._threads = threads
        SERVER.streamable_http_app()  # makes the SDK's session manager
        self._manager = SERVER.session_manager
        self._ready: asyncio.Event | None = None
        self._serving: asyncio.Task[None] | None = None

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        header = dict(scope.get("headers") or []).get(b"authorization", b"")
        caller = await self.run(lambda: _authenticate(header))
        if isinstance(caller, str):
            await _refuse(send, caller)
            return
        await self._started()
        await self._manager.handle_request({**scope, CALL: Call(caller=caller, run=self.run)}, receive, send)

    async def run(self, work: Callable[[], T]) -> T:
        """`work()` on a borrowed request thread, between Django's per-request connection checks."""
        thread = await self._threads.borrow()
        try:
            context = contextvars.copy_context()
            return await asyncio.get_running_loop().run_in_executor(thread, context.run, _in_django, work)
        finally:
            self._threads.give_back(thread)

    async def _started(self) -> None:
        if self._ready is None:
            self._ready = asyncio.Event()
            self._serving = asyncio.get_running_loop().create_task(self._serve(self._ready))
        await self._ready.wait()

    async def _serve(self, ready: asyncio.Event) -> None:
        async with self._manager.run():
            ready.set()
            await asyncio.Event().wait()  # for as long as the process serves


def _in_django(work: Callable[[], T]) -> T:
    close_old_connections()  # as Django does at a request's start and end
    try:
        return work()
    finally:
        close_old_connections()


def _authenticate(header: bytes) -> Caller | str:
    """The caller `Authorization: <header>` names, or why it is refused (the API's words)."""
    try:
        found = BearerTokenAuthentication().authenticate(SimpleNamespace(headers={"authorization": header}))
    except AuthenticationFailed as error:
        return str(error.detail)
    if found is not None:
        token = found[1]
        return Caller(actor=token_actor(token.name), name=token.name, read_only=token.read_only)
    if not settings.API_AUTH:
        return Caller(actor=ANONYMOUS, name=None, read_only=False)
    return NOT_AUTHENTICATED


async def _refuse(send: Any, detail: str) -> None:
    """The API's 401: `{"detail": ...}` and the bearer challenge."""
    body = json.dumps({"detail": detail}).encode()
    challenge = BearerTokenAuthentication().authenticate_header(None).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        (b"www-authenticate", challenge),
    ]
    await send({"type": "http.response.start", "status": 401, "headers": headers})
    await send({"type": "http.response.body", "body": body})
