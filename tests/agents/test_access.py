"""/mcp takes the API's credentials: a read-only token sees and may call the reading tools only; no token,
an unknown or a revoked one is refused; writes are recorded under the token, marked as through MCP."""

import httpx
import pytest
import requests
from django.conf import settings

from access.models import WriteRecord
from access.services import api_token_create, api_token_revoke
from tests.agents.conftest import Mcp, text, with_session
from tests.conftest import API_TOKEN_NAME
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

INITIALIZE = {
    "jsonrpc": "2.0",
    "id": 1,
    "method": "initialize",
    "params": {
        "protocolVersion": "2025-06-18",
        "capabilities": {},
        "clientInfo": {"name": "t", "version": "1"},
    },
}
MCP_HEADERS = {"Accept": "application/json, text/event-stream"}


def test_a_read_only_token_sees_and_calls_only_the_reading_tools(read_only_mcp, mcp, api, unique):
    tools = read_only_mcp.tools()
    assert "get_fleet_summary" in tools and "get_mission" in tools
    assert not {"create_robot", "dispatch_mission", "cancel_mission", "create_mission"} & set(tools)
    assert all(tool.annotations.readOnlyHint for tool in tools.values())
    refused = read_only_mcp.call("create_robot", name=unique("r"))
    assert refused.isError and 'The token "reader" is read-only' in text(refused)
    assert api.get("/robot").json() == []
    assert read_only_mcp.ok("test_mission_dispatch_connection").structuredContent["read_only"] is True


def test_no_token_an_unknown_or_a_revoked_one_is_refused(server, db):
    url = f"{server.api_url}/mcp"
    bare = requests.post(url, json=INITIALIZE, headers=MCP_HEADERS, timeout=10)
    assert bare.status_code == 401 and bare.headers["WWW-Authenticate"].startswith("Bearer")
    assert "Authorization: Bearer" in bare.json()["detail"]
    unknown = {**MCP_HEADERS, "Authorization": "Bearer abc.def"}
    assert requests.post(url, json=INITIALIZE, headers=unknown, timeout=10).status_code == 401

    _, key = api_token_create(name="soon-revoked")
    assert Mcp(server.api_url, key).ok("get_fleet_summary")
    api_token_revoke(name="soon-revoked")
    revoked = {**MCP_HEADERS, "Authorization": f"Bearer {key}"}

    # The API process takes the token as usable for FLEET_API_TOKEN_CACHE_SECONDS after its last lookup
    # (the wait's room beyond that: a slow machine).
    def refusal() -> dict[str, str] | None:
        answer = requests.post(url, json=INITIALIZE, headers=revoked, timeout=10)
        return answer.json() if answer.status_code == 401 else None  # (a 401 Response is falsy)

    refused_with = wait_for(
        refusal, "the revoked token refused", timeout=settings.API_TOKEN_CACHE_SECONDS + 5
    )
    assert "revoked" in refused_with["detail"]
    with pytest.raises(Exception) as refused:  # the SDK's client gets the 401 as an HTTP error
        with_session(server.api_url, key, lambda session: session.list_tools())
    assert "401" in repr(refused.value) or any(
        isinstance(error, httpx.HTTPStatusError) for error in getattr(refused.value, "exceptions", [])
    )


def test_writes_are_recorded_under_the_token_as_through_mcp(mcp, api, unique):
    robot, mission = unique("r"), unique("m")
    mcp.ok("create_robot", name=robot)
    mcp.ok("dispatch_mission", robot=robot, x=1, y=2, mission_name=mission)
    mcp.ok("cancel_mission", name=mission)
    assert api.post("/robot", {"name": unique("rest")}).status_code == 200
    actor = f"token:{API_TOKEN_NAME}"
    records = list(WriteRecord.objects.order_by("id").values_list("actor", "action", "object_name", "via"))
    assert records == [
        (actor, "robot_create", robot, "mcp"),
        (actor, "mission_create", mission, "mcp"),
        (actor, "mission_cancel", mission, "mcp"),
        (actor, "robot_create", unique("rest"), ""),  # through the REST API: not marked
    ]
