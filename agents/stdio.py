"""The MCP server over stdio, for desktop clients (Claude Desktop, Cursor): a small process that serves the
tools of a running Mission Dispatch's /mcp, over HTTP with a token, to the client on its stdin and stdout.

It imports no Django: it needs neither the database nor the settings, only the server's URL and a token
(MISSION_DISPATCH_URL, the reference's variable, and MISSION_DISPATCH_TOKEN). Each tool list and tool call
is passed on as it is, so the server decides what the token sees and may do.
"""

import argparse
import asyncio
import os
import sys
from collections.abc import Sequence

from mcp import ClientSession, types
from mcp.client.streamable_http import streamable_http_client
from mcp.server.lowlevel import Server
from mcp.server.stdio import stdio_server
from mcp.shared._httpx_utils import create_mcp_http_client

URL_VARIABLE = "MISSION_DISPATCH_URL"
TOKEN_VARIABLE = "MISSION_DISPATCH_TOKEN"
DEFAULT_URL = "http://localhost:5000"
SERVER_NAME = "mission-dispatch"


async def serve(url: str, token: str) -> None:
    """Serve `url`'s tools on stdio until the client closes stdin."""
    endpoint = url.rstrip("/") + "/mcp"
    async with (
        create_mcp_http_client(headers={"Authorization": f"Bearer {token}"}) as http,
        streamable_http_client(endpoint, http_client=http, terminate_on_close=False) as (read, write, _),
        ClientSession(read, write) as remote,
    ):
        started = await remote.initialize()
        server: Server = Server(SERVER_NAME, instructions=started.instructions)

        @server.list_tools()
        async def list_tools() -> list[types.Tool]:
            return (await remote.list_tools()).tools

        @server.call_tool(validate_input=False)  # the server validates, and says so in its own words
        async def call_tool(name: str, arguments: dict) -> types.CallToolResult:
            return await remote.call_tool(name, arguments)

        async with stdio_server() as (stdin, stdout):
            await server.run(stdin, stdout, server.create_initialization_options())


def main(argv: Sequence[str] | None = None) -> None:
    """Console script `mission-dispatch-mcp` (and `manage.py mcp`)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--url",
        default=os.environ.get(URL_VARIABLE, DEFAULT_URL),
        help=f"The Mission Dispatch API (default: ${URL_VARIABLE}, else {DEFAULT_URL}).",
    )
    arguments = parser.parse_args(argv)
    token = os.environ.get(TOKEN_VARIABLE, "")
    if not token:
        sys.exit(f"Set {TOKEN_VARIABLE} to an API token (manage.py api_token create NAME).")
    try:
        asyncio.run(serve(arguments.url, token))
    except* Exception as errors:  # the server away, or the token refused: say so on stderr, briefly
        sys.exit(f"mission-dispatch-mcp: {arguments.url}: {'; '.join(map(_reason, errors.exceptions))}")


def _reason(error: BaseException) -> str:
    if isinstance(error, BaseExceptionGroup):
        return "; ".join(map(_reason, error.exceptions))
    return str(error) or type(error).__name__


if __name__ == "__main__":
    main()
