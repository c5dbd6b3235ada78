"""GET /mission and its filters."""

import datetime

import pytest

from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db

T0 = datetime.datetime(2024, 5, 1, 12, 0, 0, tzinfo=datetime.UTC)


def at(minutes: int) -> datetime.datetime:
    return T0 + datetime.timedelta(minutes=minutes)


def names(response) -> list[str]:
    assert response.status_code == 200, response.json()
    return [mission["name"] for mission in response.json()]


@pytest.fixture
def history() -> None:
    """Missions in submission order: two done, one running, two queued (no start time)."""
    MissionFactory(name="done_early", robot="carter01", completed=True, start_timestamp=at(0))
    MissionFactory(name="failed_mid", robot="carter02", failed=True, start_timestamp=at(10))
    MissionFactory(name="running_late", robot="carter01", running=True, start_timestamp=at(20))
    MissionFactory(name="queued_a", robot="carter01")
    MissionFactory(name="queued_b", robot="carter02")


def test_lists_every_mission_in_submission_order(api, history):
    assert names(api.get("/mission")) == ["done_early", "failed_mid", "running_late", "queued_a", "queued_b"]


def test_missions_pending_delete_are_listed(api):
    MissionFactory(name="leaving", running=True, lifecycle="PENDING_DELETE")

    assert [mission["lifecycle"] for mission in api.get("/mission").json()] == ["PENDING_DELETE"]


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ({"state": "PENDING"}, ["queued_a", "queued_b"]),
        ({"state": "RUNNING"}, ["running_late"]),
        ({"state": "COMPLETED"}, ["done_early"]),
        ({"state": "CANCELED"}, []),
        ({"robot": "carter02"}, ["failed_mid", "queued_b"]),
        ({"robot": "carter99"}, []),
        ({"started_after": "2024-05-01T12:10:00Z"}, ["failed_mid", "running_late"]),
        ({"started_after": "2024-05-01T12:10:00.001Z"}, ["running_late"]),
        ({"started_before": "2024-05-01T12:10:00Z"}, ["done_early", "failed_mid"]),
        ({"started_before": "2024-05-01T14:09:59+02:00"}, ["done_early"]),
        ({"started_after": "2024-05-01T12:05:00", "started_before": "2024-05-01T12:15:00"}, ["failed_mid"]),
        ({"started_after": "2024-05-01"}, ["done_early", "failed_mid", "running_late"]),
        ({"started_after": "2024-05-02T00:00:00Z"}, []),
        ({"state": "PENDING", "robot": "carter01"}, ["queued_a"]),
        ({"robot": "carter01", "started_after": "2024-05-01T12:00:00Z"}, ["done_early", "running_late"]),
        ({"most_recent": 1}, ["queued_b"]),
        ({"most_recent": 2}, ["queued_b", "queued_a"]),
        ({"most_recent": 3}, ["queued_b", "queued_a", "running_late"]),
        ({"most_recent": 10}, ["queued_b", "queued_a", "running_late", "failed_mid", "done_early"]),
        ({"most_recent": 0}, []),
        ({"most_recent": 2, "started_after": "2024-05-01T12:00:00Z"}, ["running_late", "failed_mid"]),
        ({"most_recent": 1, "robot": "carter02"}, ["queued_b"]),
        ({"most_recent": 1, "state": "COMPLETED"}, ["done_early"]),
        ({"most_recent": 5, "state": "RUNNING", "robot": "carter01"}, ["running_late"]),
    ],
)
def test_filters(api, history, query, expected):
    assert names(api.get("/mission", query)) == expected


@pytest.mark.parametrize(
    ("query", "field"),
    [
        ({"state": "DONE"}, "state"),
        ({"started_after": "yesterday"}, "started_after"),
        ({"started_before": "2024-13-01T00:00:00"}, "started_before"),
        ({"most_recent": "many"}, "most_recent"),
        ({"most_recent": "1.5"}, "most_recent"),
        ({"most_recent": -1}, "most_recent"),
    ],
)
def test_invalid_filter_values_are_400_located_in_the_query(api, history, query, field):
    response = api.get("/mission", query)

    assert response.status_code == 400
    [error] = response.json()["detail"]
    assert error["loc"] == ["query", field]
    assert error["msg"]


def test_injection_attempts_are_plain_values(api, history):
    assert names(api.get("/mission", {"robot": "x' OR '1'='1"})) == []
    assert api.get("/mission", {"most_recent": "1; DROP TABLE missions_mission"}).status_code == 400
