"""GET /events (server-sent events) on a real granian server and the test database: the snapshot, then
every change in feed order; resuming with Last-Event-ID without a gap or an event twice, also in the middle
of a read and across a transaction that commits after a later one; the retention window; filters per kind;
400s; authentication."""

import queue
import socket
import time
from urllib.parse import quote

import pytest
import requests
from django.contrib.auth.models import User
from django.db import transaction
from django.test import Client

from access.services import api_token_create, api_token_revoke
from changes.services import changes_trim
from missions.models import Mission
from tests.changes.conftest import CREDENTIALS_CHECK_SECONDS, KEEPALIVE_SECONDS, RETRY_MS
from tests.database import other_connection
from tests.granian_server import GranianServer
from tests.watching import Event, Events


def _mission(robot: str, name: str) -> dict:
    tree = [{"name": "go", "route": {"waypoints": [{"x": 1, "y": 1}]}}]
    return {"robot": robot, "name": name, "mission_tree": tree}


def _open(server: GranianServer, query: str, watches: list, headers: dict[str, str] | None = None) -> Events:
    stream = Events(f"{server.url}/events?{query}", {**server.auth, **(headers or {})})
    watches.append(stream)
    return stream


def _snapshot(stream: Events) -> tuple[list[Event], Event]:
    """The snapshot's events and its snapshot_end."""
    events = []
    while (event := stream.next_event()).event != "snapshot_end":
        events.append(event)
    return events, event


def _resumed(server: GranianServer, query: str, last_id: str, watches: list) -> Events:
    """A client that reconnects after `last_id`, as EventSource does."""
    return _open(server, query, watches, {"Last-Event-ID": last_id})


def test_the_snapshot_then_each_change_in_commit_order(stream_server, api, watches):
    api.post("/robot", {"name": "ev-r1"})
    api.post("/mission", _mission("ev-r1", "ev-m1"))
    api.post("/mission", _mission("ev-other", "ev-m2"))
    stream = _open(stream_server, "robot.names=ev-r1&mission.robot=ev-r1", watches)
    assert stream.response.headers["Content-Type"] == "text/event-stream"
    assert stream.response.headers["Cache-Control"] == "no-cache"
    assert stream.next().retry == RETRY_MS  # first, once
    robot, mission, end = stream.events(3)
    # The snapshot's events carry an empty id: there is no resuming in the middle of a snapshot.
    assert (robot.event, robot.id, robot.data) == ("robot", "", api.get("/robot/ev-r1").json())
    assert (mission.event, mission.id, mission.data) == ("mission", "", api.get("/mission/ev-m1").json())
    assert (end.event, end.data) == ("snapshot_end", {})
    assert end.id

    # Asked for the other way round, the snapshot is the same: robots, then missions.
    reversed_kinds = "kind=mission&kind=robot&robot.names=ev-r1&mission.robot=ev-r1"
    assert _snapshot(_open(stream_server, reversed_kinds, watches))[0] == [robot, mission]

    api.put("/robot/ev-r1", {"heartbeat_timeout": 12})
    api.post("/mission/ev-m1/cancel")
    api.post("/mission/ev-m2/cancel")  # another robot's: filtered out
    api.put("/robot/ev-r1", {"heartbeat_timeout": 13})
    events = stream.events(3)
    assert [(event.event, event.data["name"]) for event in events] == [
        ("robot", "ev-r1"),
        ("mission", "ev-m1"),
        ("robot", "ev-r1"),
    ]
    assert events[1].data == api.get("/mission/ev-m1").json()
    assert events[2].data == api.get("/robot/ev-r1").json()
    assert len({event.id for event in events}) == 3
    assert stream.quiet()


def test_a_deleted_object_comes_with_lifecycle_deleted(stream_server, api, watches):
    api.post("/robot", {"name": "ev-gone"})
    stream = _open(stream_server, "kind=robot&robot.names=ev-gone", watches)
    _snapshot(stream)
    api.delete("/robot/ev-gone")
    event = stream.next_event()
    assert (event.event, event.data["name"], event.data["lifecycle"]) == ("robot", "ev-gone", "DELETED")


def test_kinds_and_filters_per_kind(stream_server, api, watches):
    api.post("/robot", {"name": "ek-r1"})
    api.post("/robot", {"name": "ek-r2"})
    api.post("/mission", _mission("ek-r1", "ek-m1"))
    api.post("/mission", _mission("ek-r1", "ek-m2"))
    missions = _open(stream_server, "kind=mission&mission.robot=ek-r1&mission.state=CANCELED", watches)
    robots = _open(stream_server, "kind=robot&robot.names=ek-r2&robot.names=ek-r1", watches)
    assert _snapshot(missions)[0] == []
    assert [event.data["name"] for event in _snapshot(robots)[0]] == ["ek-r1", "ek-r2"]
    recent = _open(stream_server, "kind=mission&mission.robot=ek-r1&mission.most_recent=1", watches)
    assert len(_snapshot(recent)[0]) == 1  # most_recent shapes the snapshot only, as on the watch streams

    api.post("/mission/ek-m2/cancel")
    api.put("/robot/ek-r2", {"heartbeat_timeout": 7})
    event = missions.next_event()
    assert (event.event, event.data["name"], event.data["status"]["state"]) == (
        "mission",
        "ek-m2",
        "CANCELED",
    )
    event = robots.next_event()
    assert (event.event, event.data["name"], event.data["heartbeat_timeout"]) == ("robot", "ek-r2", 7.0)
    assert missions.quiet(0.5)
    assert robots.quiet(0.5)


@pytest.mark.parametrize(
    ("query", "loc"),
    [
        ("kind=plane", ["query", "kind"]),
        ("kind=robot&kind=", ["query", "kind"]),
        ("robot.state=FLYING", ["query", "robot.state"]),
        ("robot.online=perhaps", ["query", "robot.online"]),
        ("mission.started_after=yesterday", ["query", "mission.started_after"]),
        ("mission.most_recent=-1", ["query", "mission.most_recent"]),
        ("mission.state=", ["query", "mission.state"]),
        ("kind=mission&robot.names=a", ["query", "robot.names"]),
        ("last_event_id=yesterday", ["query", "last_event_id"]),
        ("last_event_id=1:2:/2:3:/x", ["query", "last_event_id"]),
        ("last_event_id=5:2:", ["query", "last_event_id"]),
        # A position the database has not reached: forged, or from another database.
        (f"last_event_id={quote('1:999999999999:')}", ["query", "last_event_id"]),
    ],
)
def test_bad_input_is_a_400_that_says_where(stream_server, query, loc):
    response = requests.get(f"{stream_server.url}/events?{query}", headers=stream_server.auth, timeout=10)
    assert response.status_code == 400, response.text
    assert response.headers["Content-Type"] == "application/json"
    assert response.json()["detail"][0]["loc"] == loc


def test_a_malformed_last_event_id_header_is_a_400(stream_server):
    headers = {**stream_server.auth, "Last-Event-ID": "not-an-id", "Accept": "text/event-stream"}
    response = requests.get(f"{stream_server.url}/events", headers=headers, timeout=10)
    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["header", "Last-Event-ID"]


def test_events_need_credentials_a_staff_session_will_do(stream_server, watches):
    url = f"{stream_server.url}/events"
    assert requests.get(url, timeout=10).status_code == 401
    assert requests.get(url, headers={"Authorization": "Bearer nope"}, timeout=10).status_code == 401
    for staff in (True, False):
        user = User.objects.create_user(f"ev-{staff}", password="secret-password", is_staff=staff)
        browser = Client()
        browser.force_login(user)
        # What EventSource sends on a same-origin page: the session cookie, no CSRF token (a GET).
        cookie = {"Cookie": f"sessionid={browser.cookies['sessionid'].value}", "Accept": "text/event-stream"}
        if staff:
            stream = Events(f"{url}?kind=robot&robot.names=ev-none", cookie)
            watches.append(stream)
            assert _snapshot(stream)[0] == []
        else:
            response = requests.get(url, headers=cookie, timeout=10)
            assert response.status_code == 403
            assert response.json()["detail"] == "Only staff users may use the API through a session."


def _until_ended(stream: Events, seconds: float) -> list[Event]:
    """The stream's events until it ends, which must be within `seconds`."""
    events, deadline = [], time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        try:
            block = stream.next(timeout=left)
        except queue.Empty:
            break
        if block is None:
            return events
        if block.event is not None:
            events.append(block)
    raise AssertionError(f"the stream did not end within {seconds} s; its events: {events}")


def test_a_stream_ends_once_its_token_or_session_no_longer_authenticates(stream_server, api, watches):
    """A stream is authenticated when it opens; revoking its token, logging its session out, or taking
    its user's staff status ends it with an error (within FLEET_STREAM_CREDENTIALS_CHECK_SECONDS), and
    nothing of later changes reaches it. Streams whose credentials still hold go on."""
    query = "kind=robot&robot.names=ev-cred"
    _, revoked_key = api_token_create(name="ev-revoked")
    browsers = {}
    for name in ("ev-logged-out", "ev-demoted", "ev-staying"):
        browsers[name] = Client()
        browsers[name].force_login(User.objects.create_user(name, password="secret-password", is_staff=True))
    url = f"{stream_server.url}/events?{query}"
    streams = {
        "token": Events(url, {"Authorization": f"Bearer {revoked_key}"}),
        # As a browser's EventSource: the session's cookie only.
        **{
            name: Events(url, {"Cookie": f"sessionid={browser.cookies['sessionid'].value}"})
            for name, browser in browsers.items()
        },
        "server token": Events(url, stream_server.auth),
    }
    watches.extend(streams.values())
    for stream in streams.values():
        assert _snapshot(stream)[0] == []
    api_token_revoke(name="ev-revoked")
    browsers["ev-logged-out"].logout()
    User.objects.filter(username="ev-demoted").update(is_staff=False)
    api.post("/robot", {"name": "ev-cred"})
    for name in ("token", "ev-logged-out", "ev-demoted"):
        events = _until_ended(streams[name], seconds=10 * CREDENTIALS_CHECK_SECONDS)
        # The robot's creation may or may not come before the check that ends the stream; the end does.
        assert [event.event for event in events][-1:] == ["error"], name
        assert events[-1].data["error"] == "not_authenticated"
        assert [event.event for event in events[:-1]] in ([], ["robot"]), name
    for name in ("ev-staying", "server token"):
        event = streams[name].next_event()
        assert (event.event, event.data.get("name")) == ("robot", "ev-cred"), (name, event)
        assert streams[name].quiet(3 * CREDENTIALS_CHECK_SECONDS), name  # not ended: no error comes


def test_keepalives_come_while_nothing_changes_and_carry_the_resume_id(stream_server, api, watches):
    query = "kind=robot&robot.names=ev-keep"
    stream = _open(stream_server, query, watches)
    _snapshot(stream)
    keepalive = stream.next(timeout=KEEPALIVE_SECONDS * 10)
    assert (keepalive.event, keepalive.comments) == (None, ["keepalive"])
    assert keepalive.id and "/" not in keepalive.id  # a feed position: everything up to it delivered
    stream.close()
    api.post("/robot", {"name": "ev-keep"})
    resumed = _resumed(stream_server, query, keepalive.id, watches)
    event = resumed.next_event()
    assert (event.event, event.data) == ("robot", api.get("/robot/ev-keep").json())


def test_a_resume_in_the_middle_of_a_read_continues_after_the_last_event(stream_server, api, watches):
    """Three changes committed together come in one read: a client that had the first gets the other two,
    with the very ids it would have had, then what follows, and no snapshot."""
    names = ["eb-1", "eb-2", "eb-3"]
    for name in names:
        api.post("/mission", _mission("eb-robot", name))
    query = "kind=mission&mission.robot=eb-robot"
    stream = _open(stream_server, query, watches)
    _snapshot(stream)
    with transaction.atomic():
        for name in names:
            Mission.objects.filter(name=name).update(failure_reason="batch")
    batch = stream.events(3)
    assert [event.data["name"] for event in batch] == names
    assert len({event.id.split("/")[1] for event in batch}) == 1  # one read
    stream.close()

    resumed = _resumed(stream_server, query, batch[0].id, watches)
    assert resumed.events(2) == batch[1:]
    api.post("/mission/eb-1/cancel")
    event = resumed.next_event()
    assert (event.event, event.data["name"], event.data["status"]["state"]) == ("mission", "eb-1", "CANCELED")
    assert resumed.quiet()
    # The last_event_id parameter does as the header, for clients that cannot send one.
    by_parameter = _open(stream_server, f"{query}&last_event_id={quote(batch[1].id)}", watches)
    rest, after = by_parameter.events(2)
    assert rest == batch[2]
    assert (after.event, after.data) == (event.event, event.data)


def test_a_resume_misses_no_change_committed_after_a_later_one(stream_server, api, watches):
    """A transaction that wrote first (the lower change id) commits last: a client that had the later one
    and reconnects, before or after that commit, still gets it, once."""
    api.post("/mission", _mission("el-robot", "el-early"))
    api.post("/mission", _mission("el-robot", "el-late"))
    query = "kind=mission&mission.robot=el-robot"
    stream = _open(stream_server, query, watches)
    _snapshot(stream)
    with other_connection() as other:
        other.execute(f"UPDATE {Mission._meta.db_table} SET failure_reason = 'early' WHERE name = 'el-early'")
        Mission.objects.filter(name="el-late").update(failure_reason="late")  # commits first
        late = stream.next_event()
        assert late.data["status"]["failure_reason"] == "late"
        stream.close()
        before_commit = _resumed(stream_server, query, late.id, watches)
        assert before_commit.quiet(0.5)
        other.commit()
    after_commit = _resumed(stream_server, query, late.id, watches)
    for resumed in (before_commit, after_commit):
        event = resumed.next_event()
        assert (event.data["name"], event.data["status"]["failure_reason"]) == ("el-early", "early")
        assert resumed.quiet(0.5)


def test_a_resume_from_before_the_retention_window_gets_a_new_snapshot(stream_server, api, watches, settings):
    api.post("/robot", {"name": "ex-1"})
    query = "kind=robot&robot.names=ex-1"
    stream = _open(stream_server, query, watches)
    _snapshot(stream)
    api.put("/robot/ex-1", {"heartbeat_timeout": 3})
    seen = stream.next_event()
    stream.close()
    settings.CHANGE_RETENTION_SECONDS = 0
    assert changes_trim() > 0  # every change so far, the one after `seen` too

    resumed = _resumed(stream_server, query, seen.id, watches)
    error = resumed.next_event()
    assert (error.event, error.data["error"]) == ("error", "resume_expired")
    events, end = _snapshot(resumed)
    assert [event.data for event in events] == [api.get("/robot/ex-1").json()]
    assert [event.id for event in events] == [""]  # the expired id is forgotten
    assert end.id
    api.put("/robot/ex-1", {"heartbeat_timeout": 4})
    assert resumed.next_event().data["heartbeat_timeout"] == 4.0


def test_streams_and_rest_share_the_api_port_and_its_token(stream_server, watches):
    """No redirect to another port (which requests and curl would follow without the Authorization
    header): the streams answer on the API's own port, with its token, beside REST requests."""
    auth = stream_server.auth
    created = requests.post(f"{stream_server.url}/robot", json={"name": "ep-1"}, headers=auth, timeout=10)
    assert created.status_code == 200, created.text
    for path in ("/events?kind=robot&robot.names=ep-1", "/robot/watch?names=ep-1"):
        response = requests.get(
            f"{stream_server.url}{path}", headers=auth, stream=True, allow_redirects=False, timeout=(5, 30)
        )
        assert response.status_code == 200, path
        response.raw.connection.sock.shutdown(socket.SHUT_RDWR)  # hang up: the body never ends
        response.close()
    stream = _open(stream_server, "kind=robot&robot.names=ep-1", watches)
    assert [event.data["name"] for event in _snapshot(stream)[0]] == ["ep-1"]
    response = requests.put(
        f"{stream_server.url}/robot/ep-1", json={"heartbeat_timeout": 9}, headers=auth, timeout=10
    )
    assert response.status_code == 200, response.text
    assert stream.next_event().data["heartbeat_timeout"] == 9.0
