"""Who may call which endpoint, for every endpoint the URLconf has (tests/access/endpoints.py): 401 without
usable credentials, 403 for a read-only token's writes, reads for any usable token; public endpoints open."""

import time
from datetime import timedelta

import pytest
from django.test import override_settings
from django.utils import timezone
from rest_framework.test import APIClient

from access import selectors
from access.models import ApiToken, WriteRecord
from access.permissions import NOT_AUTHENTICATED
from access.services import api_token_create, api_token_revoke
from fleet.serving import STREAM_PATHS
from missions.models import Mission
from robots.models import Robot
from stations.models import Station
from tests.access.endpoints import PUBLIC_PATHS, Endpoint, endpoints
from tests.conftest import authenticated_client
from tests.factories import CAN_CHARGE, MissionFactory, RobotFactory, StationFactory, ZoneSetFactory
from zones.models import ZoneGrant

pytestmark = pytest.mark.django_db

NAME = "acc1"  # the robot and the mission every path parameter names
ENDPOINTS = endpoints(NAME)
PROTECTED = [endpoint for endpoint in ENDPOINTS if endpoint.path not in PUBLIC_PATHS]
PUBLIC = [endpoint for endpoint in ENDPOINTS if endpoint.path in PUBLIC_PATHS]
READS = [endpoint for endpoint in PROTECTED if not endpoint.writes]
WRITES = [endpoint for endpoint in PROTECTED if endpoint.writes]
# A body each write accepts (the read-write case must reach the view, not stop at validation).
WRITE_BODIES = {
    "POST /robot": {"name": "acc2"},
    "PUT /robot/acc1": {"heartbeat_timeout": 10},
    "POST /mission": {"name": "acc2", "robot": NAME, "mission_tree": [{"name": "c", "constant": {}}]},
    "POST /mission/acc1/update": {},
    "POST /robot/acc1/map": {"action": "enableMap", "map_id": "warehouse", "map_version": "1"},
    "POST /station": {"name": "acc2", "kind": "PARKING", "pose": {}},
    "PUT /station/acc1": {"kind": "PARKING", "pose": {}},
    "POST /zone_set": {"name": "acc2", "map_id": "map", "zones": []},
    "POST /zone_set/acc1/revoke": {"robot": NAME, "zone_id": "square"},
}
WRITE_QUERIES = {"POST /robot/acc1/teleop": "?params=STOP"}


@pytest.fixture(autouse=True)
def objects(request: pytest.FixtureRequest) -> None:
    # A robot with maps, online and able to charge (POST /robot/acc1/charge).
    RobotFactory(
        name=NAME,
        protocol_version="2.1.0",
        online=True,
        factsheet=CAN_CHARGE,
    )
    MissionFactory(name=NAME, robot=NAME)
    StationFactory(name=NAME)
    # Disabled, so that DELETE may remove it; enabled for a revoke (only an enabled set's grants are).
    endpoint = getattr(request.node, "callspec", None) and request.node.callspec.params.get("endpoint")
    ZoneSetFactory(name=NAME, enabled=str(endpoint) == "POST /zone_set/acc1/revoke")
    ZoneGrant.objects.create(map_id="map", zone_id="square", robot=NAME, granted_at=timezone.now())


def answered(endpoint: Endpoint) -> int:
    """The status of an allowed request: 200, but the streams need the ASGI application, not this test
    client's WSGI one (tests/changes has the streams themselves)."""
    return 501 if endpoint.path in STREAM_PATHS else 200


def call(client: APIClient, endpoint: Endpoint):
    key = str(endpoint)
    return getattr(client, endpoint.method)(
        endpoint.path + WRITE_QUERIES.get(key, ""), WRITE_BODIES.get(key), format="json"
    )


def assert_unauthenticated(response, endpoint: Endpoint) -> None:
    assert response.status_code == 401, f"{endpoint}: {response.status_code} {response.content[:200]}"
    assert response["WWW-Authenticate"].startswith("Bearer"), endpoint
    assert isinstance(response.json()["detail"], str), endpoint


def test_the_walk_finds_every_endpoint_of_the_reference_and_ours():
    assert {str(endpoint) for endpoint in ENDPOINTS} >= {
        "GET /robot",
        "POST /robot",
        "PUT /robot/acc1",
        "POST /robot/acc1/teleop",
        "POST /robot/acc1/charge",
        "GET /robot/acc1/map",
        "POST /robot/acc1/map",
        "POST /mission/acc1/cancel",
        "POST /mission/acc1/update",
        "DELETE /mission/acc1",
        "GET /metrics",
        "GET /behaviors",
        "GET /robot/watch",
        "GET /mission/watch",
        "GET /events",
        "GET /station",
        "POST /station",
        "GET /station/acc1",
        "PUT /station/acc1",
        "DELETE /station/acc1",
        "GET /station/watch",
        "GET /zone_set",
        "POST /zone_set",
        "GET /zone_set/acc1",
        "DELETE /zone_set/acc1",
        "POST /zone_set/acc1/enable",
        "POST /zone_set/acc1/disable",
        "POST /zone_set/acc1/revoke",
        "GET /zone_set/watch",
    }
    assert {endpoint.path for endpoint in PUBLIC} == PUBLIC_PATHS


@pytest.mark.parametrize("endpoint", PROTECTED, ids=str)
def test_without_a_token_every_protected_endpoint_answers_401(endpoint):
    response = call(APIClient(), endpoint)

    assert_unauthenticated(response, endpoint)
    assert response.json() == {"detail": NOT_AUTHENTICATED}


@pytest.mark.parametrize("endpoint", PROTECTED, ids=str)
@pytest.mark.parametrize(
    "header",
    ["Bearer abcdefgh.0123456789abcdef0123456789abcdef", "Bearer not-a-token\x7f", "Bearer ", "Bearer a.b.c"],
    ids=["unknown", "garbage", "empty", "dots"],
)
def test_a_bad_token_answers_401_everywhere(endpoint, header):
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=header)

    assert_unauthenticated(call(client, endpoint), endpoint)


@pytest.mark.parametrize("endpoint", PROTECTED, ids=str)
def test_a_revoked_token_answers_401_everywhere(endpoint):
    _, key = api_token_create(name="gone")
    api_token_revoke(name="gone")

    response = call(authenticated_client(key), endpoint)

    assert_unauthenticated(response, endpoint)
    assert "revoked" in response.json()["detail"]


@pytest.mark.parametrize("endpoint", WRITES, ids=str)
def test_a_read_only_token_may_not_write(endpoint):
    _, key = api_token_create(name="dashboard", read_only=True)

    response = call(authenticated_client(key), endpoint)

    assert response.status_code == 403, f"{endpoint}: {response.content[:200]}"
    assert response.json() == {
        "detail": f'The token "dashboard" is read-only: it may not {endpoint.method.upper()}.'
    }
    assert not WriteRecord.objects.exists()
    assert Robot.objects.get(name=NAME).heartbeat_timeout != 10
    assert Mission.objects.filter(name=NAME).exists()
    assert Station.objects.get(name=NAME).kind == "CHARGER"


@pytest.mark.parametrize("endpoint", READS, ids=str)
def test_a_read_only_token_reads_everything(endpoint):
    _, key = api_token_create(name="dashboard", read_only=True)

    response = call(authenticated_client(key), endpoint)

    assert response.status_code == answered(endpoint), f"{endpoint}: {response.content[:200]}"


@pytest.mark.parametrize("endpoint", WRITES, ids=str)
def test_a_read_write_token_writes(endpoint, api_token):
    response = call(authenticated_client(api_token), endpoint)

    assert response.status_code == 200, f"{endpoint}: {response.content[:300]}"
    assert WriteRecord.objects.filter(actor="token:tests").count() == 1


@pytest.mark.parametrize("endpoint", PUBLIC, ids=str)
@pytest.mark.parametrize(
    "header", [None, "Bearer abcdefgh.0123456789abcdef0123456789abcdef"], ids=["none", "bad"]
)
def test_public_endpoints_are_open_whatever_the_request_carries(endpoint, header):
    client = APIClient()
    if header:
        client.credentials(HTTP_AUTHORIZATION=header)

    assert call(client, endpoint).status_code == 200


@override_settings(API_AUTH=False)
@pytest.mark.parametrize("endpoint", PROTECTED, ids=str)
def test_open_mode_needs_no_credentials_and_records_writes_as_anonymous(endpoint):
    response = call(APIClient(), endpoint)

    assert response.status_code == answered(endpoint), f"{endpoint}: {response.content[:300]}"
    assert set(WriteRecord.objects.values_list("actor", flat=True)) == (
        {"anonymous"} if endpoint.writes else set()
    )


@override_settings(API_AUTH=False)
def test_open_mode_ignores_tokens_even_bad_ones():
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION="Bearer abcdefgh.0123456789abcdef0123456789abcdef")

    assert client.get("/robot").status_code == 200


def test_an_expired_token_answers_401():
    token, key = api_token_create(name="temp")
    ApiToken.objects.filter(pk=token.pk).update(expiry_date=timezone.now() - timedelta(seconds=1))

    response = authenticated_client(key).get("/robot")

    assert response.status_code == 401
    assert response.json() == {"detail": "Invalid token: unknown, revoked or expired."}


def test_a_token_used_once_is_taken_as_usable_for_the_cache_time_and_then_looked_up_again():
    _, key = api_token_create(name="cached")
    client = authenticated_client(key)
    with override_settings(API_TOKEN_CACHE_SECONDS=2.0):
        assert client.get("/robot").status_code == 200
        looked_up = time.monotonic()
        ApiToken.objects.filter(name="cached").update(revoked=True)  # as another process's revoke does

        assert client.get("/robot").status_code == 200  # not asked again
        time.sleep(max(0.0, looked_up + 2.0 - time.monotonic()))

        assert client.get("/robot").status_code == 401


def test_a_token_revoked_by_this_process_or_expired_is_refused_at_once_though_cached():
    _, revoked = api_token_create(name="revoked")
    token, expiring = api_token_create(name="expiring")
    expiry = timezone.now() + timedelta(seconds=0.5)
    ApiToken.objects.filter(pk=token.pk).update(expiry_date=expiry)
    with override_settings(API_TOKEN_CACHE_SECONDS=60):
        assert authenticated_client(revoked).get("/robot").status_code == 200
        assert authenticated_client(expiring).get("/robot").status_code == 200
        assert expiring in selectors._usable  # cached for a minute

        time.sleep(max(0.0, (expiry - timezone.now()).total_seconds()) + 0.05)
        assert authenticated_client(expiring).get("/robot").status_code == 401

        api_token_revoke(name="revoked")
        assert authenticated_client(revoked).get("/robot").status_code == 401


def test_without_the_cache_every_request_looks_the_token_up():
    _, key = api_token_create(name="uncached")
    client = authenticated_client(key)
    with override_settings(API_TOKEN_CACHE_SECONDS=0):
        assert client.get("/robot").status_code == 200
        ApiToken.objects.filter(name="uncached").update(revoked=True)

        assert client.get("/robot").status_code == 401


def test_a_token_with_a_known_prefix_and_another_secret_answers_401():
    _, key = api_token_create(name="real")
    prefix, _, secret = key.partition(".")
    forged = f"{prefix}.{secret[::-1]}"
    assert forged != key

    assert authenticated_client(forged).get("/robot").status_code == 401
    assert authenticated_client(key).get("/robot").status_code == 200


def test_a_token_records_when_it_was_last_used():
    token, key = api_token_create(name="seen")
    assert token.last_used is None

    authenticated_client(key).get("/robot")

    token.refresh_from_db()
    assert token.last_used is not None
