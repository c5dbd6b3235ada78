"""The MCP server against real services: the end-to-end stack (granian serving the API and /mcp, bridge,
worker, beat) on the test database, simulated robots, and the SDK's own client."""

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar

import pytest
from mcp import ClientSession
from mcp.client.streamable_http import streamable_http_client
from mcp.shared._httpx_utils import create_mcp_http_client
from mcp.types import CallToolResult

from access.services import api_token_create
from tests.e2e.conftest import recorder, simulator, stack, unique
from tests.granian_server import healthy
from tests.waiting import wait_for

__all__ = ["recorder", "simulator", "stack", "unique"]

T = TypeVar("T")


def with_session(url: str, token: str | None, work: Callable[[ClientSession], Awaitable[T]]) -> T:
    """`work(session)` with an initialized MCP session to `url`/mcp, authenticated with `token`."""
    headers = {"Authorization": f"Bearer {token}"} if token is not None else {}

    async def run() -> T:
        async with (
            create_mcp_http_client(headers=headers) as http,
            streamable_http_client(f"{url}/mcp", http_client=http, terminate_on_close=False) as streams,
            ClientSession(streams[0], streams[1]) as session,
        ):
            await session.initialize()
            return await work(session)

    return asyncio.run(run())


class Mcp:
    """Calls of one token to the stack's MCP server, each in a session of its own."""

    def __init__(self, url: str, token: str) -> None:
        self.url, self.token = url, token

    def call(self, tool: str, **arguments: Any) -> CallToolResult:
        return with_session(self.url, self.token, lambda session: session.call_tool(tool, arguments))

    def ok(self, tool: str, **arguments: Any) -> CallToolResult:
        """The call's result, which must not be an error."""
        result = self.call(tool, **arguments)
        assert not result.isError, text(result)
        return result

    def tools(self) -> dict[str, Any]:
        async def listed(session: ClientSession) -> dict[str, Any]:
            return {tool.name: tool for tool in (await session.list_tools()).tools}

        return with_session(self.url, self.token, listed)


def text(result: CallToolResult) -> str:
    return "".join(getattr(block, "text", "") for block in result.content)


@pytest.fixture
def server(stack: Any) -> Any:
    """The stack, its API process (REST, streams and /mcp) up."""
    wait_for(lambda: healthy(stack.api_url), message="the API process answering")
    return stack


@pytest.fixture
def mcp(server: Any, api_token: str) -> Mcp:
    """The read-write token of the `api` fixture, on the stack's MCP server."""
    return Mcp(server.api_url, api_token)


@pytest.fixture
def read_only_mcp(server: Any, db: None) -> Mcp:
    return Mcp(server.api_url, api_token_create(name="reader", read_only=True)[1])
