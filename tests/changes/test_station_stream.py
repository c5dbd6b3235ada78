"""Stations in the change feed: GET /station/watch and GET /events?kind=station on a real API process
(granian ASGI) and the test database, as robots and missions are watched."""

import requests

from tests.watching import Events, Watch

CHARGER = {"kind": "CHARGER", "pose": {"x": 1.0, "y": 2.0, "map_id": "map"}}


def test_a_station_watch_gives_the_snapshot_then_each_change_as_get_shows_it(stream_server, api, watches):
    api.post("/station", {**CHARGER, "name": "sw-1"}, format="json")
    api.post("/station", {"name": "sw-p", "kind": "PARKING", "pose": {}}, format="json")
    watch = Watch(f"{stream_server.url}/station/watch?kind=CHARGER", stream_server.auth)
    watches.append(watch)
    assert watch.response.headers["Content-Type"] == "application/x-ndjson"
    assert watch.next() == api.get("/station/sw-1").json()  # the parking station is filtered out

    api.put("/station/sw-1", {**CHARGER, "capacity": 2}, format="json")
    assert watch.next() == api.get("/station/sw-1").json()
    api.put("/station/sw-p", {"kind": "PARKING", "pose": {"x": 3.0}}, format="json")
    api.delete("/station/sw-1")
    line = watch.next()
    assert (line["name"], line["lifecycle"], line["capacity"]) == ("sw-1", "DELETED", 2)
    assert watch.quiet(0.5)


def test_events_show_stations_by_kind_with_their_filters(stream_server, api, watches):
    api.post("/station", {**CHARGER, "name": "se-1"}, format="json")
    stream = Events(f"{stream_server.url}/events?kind=station&station.map_id=map", stream_server.auth)
    watches.append(stream)
    stream.next()  # retry
    station, end = stream.events(2)
    assert (station.event, station.data) == ("station", api.get("/station/se-1").json())
    assert end.event == "snapshot_end"

    api.post("/robot", {"name": "se-robot"}, format="json")  # not asked for
    api.post("/station", {**CHARGER, "name": "se-2", "robot_types": ["CARRIER"]}, format="json")
    event = stream.next_event()
    assert (event.event, event.data) == ("station", api.get("/station/se-2").json())
    assert event.id


def test_an_unknown_station_filter_is_a_400(stream_server):
    response = requests.get(
        f"{stream_server.url}/events?kind=station&station.kind=DOCK", headers=stream_server.auth, timeout=10
    )
    assert response.status_code == 400
    assert response.json()["detail"][0]["loc"] == ["query", "station.kind"]
