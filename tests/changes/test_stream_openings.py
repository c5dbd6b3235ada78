"""Streams that open at once (hundreds of watchers reconnecting after a restart) take turns for their
requests' database connections (FLEET_STREAM_OPENINGS), on a real API process and the test database."""

import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import requests
from django.db import connection

from access.services import api_token_create
from tests.database import other_connection
from tests.granian_server import ASGI, GranianServer, granian_server
from tests.waiting import wait_for
from tests.watching import Watch

OPENINGS = 2
WATCHES = 12


@pytest.fixture
def server(transactional_db: None, tmp_path: Path) -> Iterator[GranianServer]:
    _, token = api_token_create(name="stream-openings")
    env = {"FLEET_STREAM_OPENINGS": str(OPENINGS), "FLEET_WATCH_POLL_SECONDS": "0.05"}
    with granian_server(ASGI, log=tmp_path / "api.log", token=token, env=env) as server:
        yield server


def _requests_waiting_for_the_lock() -> int:
    with other_connection() as watcher:
        return watcher.execute(
            "SELECT count(*) FROM pg_stat_activity WHERE datname = %s AND wait_event_type = 'Lock' "
            "AND backend_type = 'client backend'",
            [connection.settings_dict["NAME"]],
        ).fetchone()[0]


def test_streams_opened_at_once_take_turns_for_the_database(server, api, watches):
    api.post("/robot", {"name": "so-1"})
    url = f"{server.url}/robot/watch?names=so-1"
    with other_connection() as locker, ThreadPoolExecutor(WATCHES) as clients:
        # The snapshots wait for this lock, each holding its request's database connection meanwhile.
        locker.execute("LOCK TABLE robots_robot IN ACCESS EXCLUSIVE MODE")
        opened = [clients.submit(Watch, url, server.auth) for _ in range(WATCHES)]

        wait_for(lambda: _requests_waiting_for_the_lock() == OPENINGS, message="the first openings")
        time.sleep(1.0)  # the others had their time to connect, and wait their turn without a connection
        assert _requests_waiting_for_the_lock() == OPENINGS
        assert not any(each.done() for each in opened)

        locker.rollback()
        watches.extend(each.result(timeout=60) for each in opened)

    assert [watch.next()["name"] for watch in watches] == ["so-1"] * WATCHES
    api.put("/robot/so-1", {"heartbeat_timeout": 12})
    assert all(watch.next()["heartbeat_timeout"] == 12 for watch in watches)


def test_a_refused_stream_ends_its_turn(server, api, watches):
    """Refused requests (no credentials, bad filters) end their turns too: more of them than there are turns
    leave a stream that comes after them unhindered."""
    api.post("/robot", {"name": "so-2"})
    for _ in range(OPENINGS + 1):
        assert requests.get(f"{server.url}/robot/watch", timeout=10).status_code == 401
        url = f"{server.url}/robot/watch?state=FLYING"
        assert requests.get(url, headers=server.auth, timeout=10).status_code == 400
    watch = Watch(f"{server.url}/robot/watch?names=so-2", server.auth)
    watches.append(watch)
    assert watch.next()["name"] == "so-2"
