"""The stdio transport end to end: a desktop client starts `mission-dispatch-mcp`, which serves the running
server's tools with the token from its environment."""

import asyncio
import os
import subprocess
import sys
from pathlib import Path

import pytest
from mcp import ClientSession, StdioServerParameters
from mcp.client.stdio import stdio_client

from tests.agents.conftest import text

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

CONSOLE_SCRIPT = str(Path(sys.executable).with_name("mission-dispatch-mcp"))
ROOT = Path(__file__).resolve().parents[2]


def _through_stdio(url: str, token: str, robot: str) -> tuple[set[str], str, str]:
    server = StdioServerParameters(
        command=CONSOLE_SCRIPT,
        args=["--url", url],
        env={**os.environ, "MISSION_DISPATCH_TOKEN": token},
    )

    async def run() -> tuple[set[str], str, str]:
        async with stdio_client(server) as (read, write), ClientSession(read, write) as session:
            await session.initialize()
            tools = {tool.name for tool in (await session.list_tools()).tools}
            created = await session.call_tool("create_robot", {"name": robot})
            refused = await session.call_tool("create_robot", {"name": robot})
            assert not created.isError and refused.isError
            return tools, text(created), text(refused)

    return asyncio.run(run())


def test_stdio_serves_the_running_servers_tools(server, api, api_token, unique):
    robot = unique("desk")
    tools, created, refused = _through_stdio(server.api_url, api_token, robot)
    assert {"dispatch_mission", "get_fleet_summary", "create_mission"} <= tools
    assert f"**{robot}**" in created
    assert f"Object robot with name {robot} already exists" in refused
    assert api.get(f"/robot/{robot}").status_code == 200


@pytest.mark.parametrize("command", [[CONSOLE_SCRIPT], [sys.executable, "manage.py", "mcp"]])
def test_stdio_without_a_token_says_so(server, command):
    env = {key: value for key, value in os.environ.items() if key != "MISSION_DISPATCH_TOKEN"}
    done = subprocess.run(
        [*command, "--url", server.api_url], cwd=ROOT, env=env, capture_output=True, timeout=60
    )
    assert done.returncode != 0 and b"Set MISSION_DISPATCH_TOKEN" in done.stderr
