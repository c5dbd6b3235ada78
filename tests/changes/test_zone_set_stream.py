"""Zone sets in the change feed: GET /zone_set/watch and GET /events?kind=zone_set on a real API process
(granian ASGI) and the test database, as stations are watched."""

from tests.watching import Events, Watch
from tests.zones.bodies import zone_set


def test_a_zone_set_watch_gives_the_snapshot_then_each_change_as_get_shows_it(stream_server, api, watches):
    api.post("/zone_set", zone_set(name="zw-1"), format="json")
    api.post("/zone_set", zone_set(name="zw-y", map_id="yard"), format="json")
    watch = Watch(f"{stream_server.url}/zone_set/watch?map_id=map", stream_server.auth)
    watches.append(watch)
    assert watch.response.headers["Content-Type"] == "application/x-ndjson"
    assert watch.next() == api.get("/zone_set/zw-1").json()  # the yard's set is filtered out

    api.post("/zone_set/zw-1/enable")
    assert watch.next() == api.get("/zone_set/zw-1").json()
    api.post("/zone_set/zw-y/enable")
    api.post("/zone_set/zw-1/disable")
    assert watch.next()["status"] == {"enabled": False}
    api.delete("/zone_set/zw-1")
    line = watch.next()
    assert (line["name"], line["lifecycle"]) == ("zw-1", "DELETED")
    assert watch.quiet(0.5)


def test_events_show_zone_sets_by_kind_with_their_filters(stream_server, api, watches):
    api.post("/zone_set", zone_set(name="ze-1"), format="json")
    stream = Events(f"{stream_server.url}/events?kind=zone_set&zone_set.enabled=false", stream_server.auth)
    watches.append(stream)
    stream.next()  # retry
    zones, end = stream.events(2)
    assert (zones.event, zones.data) == ("zone_set", api.get("/zone_set/ze-1").json())
    assert end.event == "snapshot_end"

    api.post(
        "/station", {"name": "ze-station", "kind": "PARKING", "pose": {}}, format="json"
    )  # not asked for
    api.post("/zone_set", zone_set(name="ze-2", map_id="yard"), format="json")
    event = stream.next_event()
    assert (event.event, event.data) == ("zone_set", api.get("/zone_set/ze-2").json())
    assert event.id
