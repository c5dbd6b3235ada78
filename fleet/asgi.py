"""The API's ASGI application (`api` in deploy/Procfile, granian's ASGI interface): the REST API and the
streams (GET /robot/watch, GET /mission/watch, GET /events) on one port, with one set of credentials.

Both go through Django's ASGI handler (ApiHandler: the middleware and the view in one call, as under
WSGI), but not on the same threads:
- A REST request borrows one of FLEET_API_THREADS threads for its whole run (middleware, view, response),
  as a WSGI server's request thread: that thread keeps its database connection from request to request,
  and at most that many requests run at once (the others wait their turn in the event loop).
- A stream's request (its authentication, validation and snapshot) runs on a thread of its own, closed
  with its database connection when the stream ends; the stream itself is a coroutine (changes.stream),
  so hundreds of open streams take none of the REST threads. At most FLEET_STREAM_OPENINGS streams' requests
  run at once, so watchers that all connect at once do not take every database connection there is.
- The MCP server (POST /mcp, `agents.http`) authenticates like the API and runs its tools' Django work on
  the REST threads.
"""

import asyncio
import contextvars
import io
import os
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from typing import IO, Any

import django
from asgiref.sync import ThreadSensitiveContext, sync_to_async
from django.conf import settings
from django.core import signals
from django.core.exceptions import RequestAborted
from django.core.handlers.asgi import ASGIHandler, get_script_prefix
from django.db import connections
from django.http import FileResponse, HttpRequest, HttpResponseBase
from django.urls import set_script_prefix

from fleet.serving import STREAM_PATHS, api_process_start

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup(set_prefix=False)  # as django.core.asgi.get_asgi_application

from agents.http import MCP_PATHS, McpEndpoint  # noqa: E402 (its tools import the apps' models)

Scope = dict[str, Any]
Message = dict[str, Any]
Receive = Callable[[], Awaitable[Message]]


class ApiHandler(ASGIHandler):
    """Django's ASGI handler, but a request's middleware and view run as under WSGI: in one call on the
    request's thread. In its async mode the handler goes back and forth between the event loop and the
    thread around each middleware (WhiteNoise's and ours are sync only), a dozen round trips a request
    that cost REST requests milliseconds (bench/HISTORY.md, "One port for the API and the streams")."""

    def load_middleware(self, is_async: bool = False) -> None:
        super().load_middleware(is_async=False)

    async def get_response_async(self, request: HttpRequest) -> HttpResponseBase:
        return await sync_to_async(self.get_response, thread_sensitive=True)(request)


class RestHandler(ApiHandler):
    """ApiHandler for REST requests: the request_started signal, the request, the view and, when the
    response's content is all there, its close (request_finished) in one call on the request's thread,
    where Django's handler goes to a thread three times; and no task that listens for the client's
    disconnect meanwhile, which a view on a thread could not heed anyway (the streams, which can, keep
    Django's handler). A streamed response (a static file) is closed after it is sent, as Django does."""

    async def serve(self, scope: Scope, receive: Receive, send: Any, thread: ThreadPoolExecutor) -> None:
        """Serve the request with `thread`, which `application` lent it. Run there in a copy of this task's
        context, as asgiref's sync_to_async would run it, without its ThreadSensitiveContext machinery,
        which cost a tenth of a REST request's CPU (bench/HISTORY.md)."""
        try:
            body = await _body(receive)
        except RequestAborted:
            return
        loop = asyncio.get_running_loop()
        context = contextvars.copy_context()
        response = await loop.run_in_executor(thread, context.run, self._respond, scope, io.BytesIO(body))
        try:
            await self.send_response(response, send)
        finally:
            if response.streaming:
                await loop.run_in_executor(thread, context.run, response.close)

    def _respond(self, scope: Scope, body_file: IO[bytes]) -> HttpResponseBase:
        set_script_prefix(get_script_prefix(scope))
        signals.request_started.send(sender=self.__class__, scope=scope)
        request, response = self.create_request(scope, body_file)
        if request is not None:
            response = self.get_response(request)
            response._handler_class = self.__class__
        if isinstance(response, FileResponse):
            response.block_size = self.chunk_size
        if not response.streaming:
            response.close()
        return response


async def _body(receive: Receive) -> bytes:
    """The request's body (at most FLEET_API_MAX_BODY_BYTES + 1 bytes, `_bounded`), in memory: Django's
    handler spools it to a temporary file, which costs more than a REST body's bytes."""
    chunks = []
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            raise RequestAborted()
        chunks.append(message.get("body", b""))
        if not message.get("more_body", False):
            return b"".join(chunks)


django_application = ApiHandler()
rest_application = RestHandler()


class RequestThreads:
    """FLEET_API_THREADS threads, each lent to one request at a time: a REST request runs its middleware,
    view and response on it, as on a WSGI server's request thread (`RestHandler`)."""

    def __init__(self, count: int) -> None:
        self._count = count
        self._free: asyncio.Queue[ThreadPoolExecutor] | None = None

    async def borrow(self) -> ThreadPoolExecutor:
        if self._free is None:  # in the server's event loop, at the first request
            self._free = asyncio.Queue()
            for number in range(self._count):
                self._free.put_nowait(ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"api-{number}"))
        return await self._free.get()

    def give_back(self, thread: ThreadPoolExecutor) -> None:
        assert self._free is not None
        self._free.put_nowait(thread)


REQUEST_THREADS = RequestThreads(settings.API_THREADS)
MCP = McpEndpoint(REQUEST_THREADS)


async def application(scope: Scope, receive: Receive, send: Any) -> None:
    receive = _bounded(receive)
    if scope["type"] == "http" and scope["path"] in STREAM_PATHS:
        await STREAM_OPENINGS.run(scope, receive, send)
        return
    if scope["type"] != "http":
        await rest_application(scope, receive, send)  # Django's handler refuses it
        return
    if scope["path"] in MCP_PATHS:
        await MCP(scope, receive, send)
        return
    thread = await REQUEST_THREADS.borrow()
    try:
        await rest_application.serve(scope, receive, send, thread)
    finally:
        REQUEST_THREADS.give_back(thread)


def _bounded(receive: Receive) -> Receive:
    """`receive`, but a body ends after FLEET_API_MAX_BODY_BYTES + 1 bytes. Django's ASGI handler reads a
    whole body (into a temporary file past 2.5 MB) before any check of its size; cut short, a body too
    large is refused by its Content-Length (body_too_large) and a chunked one for having none, as under
    WSGI, without the server storing the rest. The rest is read and dropped: after a body, Django's handler
    expects only the client's disconnect."""
    read = 0

    async def bounded() -> Message:
        nonlocal read
        limit = settings.API_MAX_BODY_BYTES
        while True:
            message = await receive()
            if message["type"] != "http.request" or read <= limit:
                break
        if message["type"] == "http.request":
            read += len(message.get("body", b""))
            if read > limit:
                message = {**message, "more_body": False}
        return message

    return bounded


class StreamOpenings:
    """FLEET_STREAM_OPENINGS streams' requests at a time: a stream's turn ends when its stream starts (its
    view let go of its database connection after the snapshot) or, for a request refused, when its
    connection is closed."""

    def __init__(self, count: int) -> None:
        self._turns = asyncio.Semaphore(count)  # bound to the server's event loop at its first wait

    async def run(self, scope: Scope, receive: Receive, send: Any) -> None:
        await self._turns.acquire()
        turn = True

        def end_turn() -> None:
            nonlocal turn
            if turn:
                turn = False
                self._turns.release()

        async def sending(message: Message) -> None:
            if message["type"] == "http.response.start" and message["status"] == 200:
                end_turn()
            await send(message)

        try:
            await _stream(scope, receive, sending)
        finally:
            end_turn()


STREAM_OPENINGS = StreamOpenings(settings.STREAM_OPENINGS)


async def _stream(scope: Scope, receive: Any, send: Any) -> None:
    """A stream's request on a thread of its own, which ends with it, and its database connection too (a
    connection left behind would stay open for good: the view lets go of it once the snapshot is read,
    this is for the requests refused before)."""
    thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stream")
    try:
        async with ThreadSensitiveContext(executor=thread):
            await django_application(scope, receive, send)
    finally:
        await asyncio.get_running_loop().run_in_executor(thread, connections.close_all)
        thread.shutdown(wait=False)


api_process_start()
