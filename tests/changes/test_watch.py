"""GET /robot/watch and GET /mission/watch on a real API process (granian ASGI) and the test database:
snapshot, changes, filters, authentication, the feed's transactions, slow watchers, database connections."""

import time

import pytest
import requests
from django.db import transaction

from changes.models import Change
from missions.models import Mission
from robots.models import Robot
from tests.changes.conftest import API_THREADS, server_connections
from tests.database import other_connection
from tests.waiting import wait_for
from tests.watching import Watch


def _mission(robot: str, name: str) -> dict:
    tree = [{"name": "go", "route": {"waypoints": [{"x": 1, "y": 1}]}}]
    return {"robot": robot, "name": name, "mission_tree": tree}


def test_a_watch_gives_the_snapshot_then_each_change_as_get_shows_it(stream_server, api, watches):
    api.post("/robot", {"name": "wa-1"})
    api.post("/robot", {"name": "wa-2"})
    watch = Watch(f"{stream_server.url}/robot/watch?names=wa-1&names=wa-2", stream_server.auth)
    watches.append(watch)
    assert watch.response.headers["Content-Type"] == "application/x-ndjson"
    assert watch.take(2) == [api.get("/robot/wa-1").json(), api.get("/robot/wa-2").json()]

    api.put("/robot/wa-2", {"heartbeat_timeout": 12})
    assert watch.next() == api.get("/robot/wa-2").json()
    api.delete("/robot/wa-1")
    line = watch.next()  # an idle robot goes at once: its last image, lifecycle DELETED
    assert (line["name"], line["lifecycle"]) == ("wa-1", "DELETED")
    assert api.get("/robot/wa-1").status_code == 400


def test_missions_stream_in_commit_order_with_nothing_repeated(stream_server, api, watches):
    watch = Watch(f"{stream_server.url}/mission/watch?robot=wm-robot", stream_server.auth)
    watches.append(watch)
    assert watch.quiet(0.5)  # no mission of that robot yet: an empty snapshot
    api.post("/mission", _mission("wm-robot", "wm-1"))
    api.post("/mission", _mission("wm-robot", "wm-2"))
    api.post("/mission", _mission("other-robot", "wm-other"))
    api.post("/mission/wm-1/cancel")
    lines = watch.take(3)
    assert [(line["name"], line["status"]["state"]) for line in lines] == [
        ("wm-1", "PENDING"),
        ("wm-2", "PENDING"),
        ("wm-1", "CANCELED"),
    ]
    assert lines[-1] == api.get("/mission/wm-1").json()
    # An update that changes nothing the API shows (a column of the engine's own) is no line.
    Mission.objects.filter(name="wm-2").update(order_accepted=True)
    assert watch.quiet(1.0)


def test_a_rolled_back_change_emits_nothing(stream_server, api, watches):
    api.post("/mission", _mission("wr-robot", "wr-1"))
    watch = Watch(f"{stream_server.url}/mission/watch?robot=wr-robot", stream_server.auth)
    watches.append(watch)
    assert watch.next()["status"]["failure_reason"] is None
    with pytest.raises(RuntimeError), transaction.atomic():
        Mission.objects.filter(name="wr-1").update(failure_reason="rolled back")
        raise RuntimeError
    Mission.objects.filter(name="wr-1").update(failure_reason="committed")
    assert watch.next()["status"]["failure_reason"] == "committed"
    assert watch.quiet(0.5)


def test_a_change_committed_after_a_later_one_is_not_lost(stream_server, api, watches):
    """A transaction takes its feed id when it writes, not when it commits: a reader that went by ids would
    skip the earlier id committed last. The stream goes by snapshots."""
    api.post("/mission", _mission("wl-robot", "wl-early"))
    api.post("/mission", _mission("wl-robot", "wl-late"))
    watch = Watch(f"{stream_server.url}/mission/watch?robot=wl-robot", stream_server.auth)
    watches.append(watch)
    watch.take(2)
    with other_connection() as other:
        other.execute(f"UPDATE {Mission._meta.db_table} SET failure_reason = 'early' WHERE name = 'wl-early'")
        Mission.objects.filter(name="wl-late").update(failure_reason="late")  # commits first
        assert watch.next()["status"]["failure_reason"] == "late"
        assert watch.quiet(0.5)
        other.commit()
    assert watch.next()["status"]["failure_reason"] == "early"
    early, late = (
        Change.objects.get(name=name, image__failure_reason=reason).id
        for name, reason in (("wl-early", "early"), ("wl-late", "late"))
    )
    assert early < late


def test_filters_select_the_snapshot_and_the_changes(stream_server, api, watches):
    api.post("/mission", _mission("wf-a", "wf-a1"))
    api.post("/mission", _mission("wf-b", "wf-b1"))
    watch = Watch(f"{stream_server.url}/mission/watch?robot=wf-a&state=CANCELED", stream_server.auth)
    watches.append(watch)
    assert watch.quiet(0.5)
    api.post("/mission/wf-b1/cancel")
    api.post("/mission/wf-a1/cancel")
    line = watch.next()
    assert (line["name"], line["status"]["state"]) == ("wf-a1", "CANCELED")
    assert watch.quiet(0.5)
    robots = Watch(f"{stream_server.url}/robot/watch?names=wf-none", stream_server.auth)
    watches.append(robots)
    api.post("/robot", {"name": "wf-other"})
    api.post("/robot", {"name": "wf-none"})
    assert robots.next()["name"] == "wf-none"


def test_watch_needs_credentials_and_valid_filters(stream_server):
    for path in ("/robot/watch", "/mission/watch"):
        response = requests.get(f"{stream_server.url}{path}", timeout=10)
        assert response.status_code == 401, response.text
        bad_token = {"Authorization": "Bearer nope"}
        assert requests.get(f"{stream_server.url}{path}", headers=bad_token, timeout=10).status_code == 401
        url = f"{stream_server.url}{path}?publisher_id=x"
        response = requests.get(url, headers=stream_server.auth, timeout=10)
        assert response.status_code == 400
        assert response.json()["detail"][0]["loc"] == ["query", "publisher_id"]
    url = f"{stream_server.url}/robot/watch?state=FLYING"
    response = requests.get(url, headers=stream_server.auth, timeout=10)
    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["query", "state"]


def test_publisher_id_is_accepted_and_watch_is_no_robot_name(stream_server, api, watches):
    api.post("/robot", {"name": "watch"})  # a robot may be called "watch": GET /robot/watch is the stream
    publisher = "publisher_id=0b7b3e2c-4a5e-4a7e-9c0e-2f0c1d2e3f40"
    watch = Watch(f"{stream_server.url}/robot/watch?names=watch&{publisher}", stream_server.auth)
    watches.append(watch)
    assert watch.next()["name"] == "watch"
    assert watch.response.headers["Content-Type"] == "application/x-ndjson"


def test_the_wsgi_application_refuses_streams(api):
    """Under WSGI (fleet.wsgi: runserver, say) a stream would hold a thread for its whole life, and Django
    cannot send an async stream there: the streams are the ASGI application's (deploy/Procfile)."""
    for path in ("/mission/watch?robot=x", "/robot/watch", "/events?kind=robot"):
        response = api.get(path)
        assert response.status_code == 501, path
        assert "fleet.asgi" in response.json()["detail"]
    api.credentials()
    assert api.get("/events").status_code == 401


def test_a_watcher_that_falls_behind_is_told_and_dropped(stream_server, api, watches):
    api.post("/robot", {"name": "ws-slow"})
    slow = Watch(f"{stream_server.url}/robot/watch?names=ws-slow", stream_server.auth, read=False)
    watches.append(slow)
    fast = Watch(f"{stream_server.url}/robot/watch?names=ws-slow", stream_server.auth)
    watches.append(fast)
    fast.next()
    # Far more changes than the socket buffers and the watcher's queue hold, while `slow` reads nothing.
    lines = 0
    while lines < 30_000:
        with transaction.atomic():
            for _ in range(20):
                Robot.objects.filter(name="ws-slow").update(battery_level=lines % 100)
                lines += 1
    slow.start_reading()
    got = []
    while (line := slow.next()) is not None:
        got.append(line)
    assert got[-1]["error"] == "watcher_behind"
    assert len(got) < 30_000
    assert fast.next()["name"] == "ws-slow"  # the others go on


def test_twenty_open_watches_leave_requests_unhindered(stream_server, api, watches):
    api.post("/robot", {"name": "wt-1"})
    for _ in range(20):
        watches.append(Watch(f"{stream_server.url}/robot/watch?names=wt-1", stream_server.auth))
    for watch in watches:
        assert watch.next()["name"] == "wt-1"
    started = time.monotonic()
    for _ in range(10):
        assert requests.get(f"{stream_server.url}/robot/wt-1", headers=stream_server.auth, timeout=10).ok
    another = Watch(f"{stream_server.url}/robot/watch?names=wt-1", stream_server.auth)
    watches.append(another)
    assert another.next()["name"] == "wt-1"
    assert time.monotonic() - started < 10
    api.put("/robot/wt-1", {"heartbeat_timeout": 5})
    assert all(watch.next()["heartbeat_timeout"] == 5.0 for watch in watches)


def test_open_streams_and_finished_requests_hold_no_database_connection(stream_server, api, watches):
    """A stream's request runs in a thread of its own: its connection must close with it (an
    unauthenticated client must not be able to use up PostgreSQL's connections), and an open stream, which
    lives for hours, must not keep its request's. The poller's one connection serves every stream; the
    REST requests' threads keep theirs, at most FLEET_API_THREADS."""
    api.post("/robot", {"name": "wc-1"})
    for _ in range(10):
        watches.append(Watch(f"{stream_server.url}/robot/watch?names=wc-1", stream_server.auth))
    for _ in range(10):
        assert requests.get(f"{stream_server.url}/robot/wc-1", headers=stream_server.auth, timeout=10).ok
        assert requests.get(f"{stream_server.url}/robot/watch", timeout=10).status_code == 401
        url = f"{stream_server.url}/robot/watch?state=FLYING"
        assert requests.get(url, headers=stream_server.auth, timeout=10).status_code == 400
    assert all(watch.next()["name"] == "wc-1" for watch in watches)
    wait_for(
        lambda: server_connections() <= 1 + API_THREADS,
        message="the stream requests' connections to close",
    )
    api.put("/robot/wc-1", {"heartbeat_timeout": 7})
    assert all(watch.next()["heartbeat_timeout"] == 7.0 for watch in watches)
