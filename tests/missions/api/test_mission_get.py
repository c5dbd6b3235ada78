"""GET /mission/{name}."""

import datetime

import pytest

from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db


def test_returns_the_mission_with_its_status(api):
    started = datetime.datetime(2024, 5, 1, 12, 0, 0, tzinfo=datetime.UTC)
    MissionFactory(
        name="m1",
        failed=True,
        start_timestamp=started,
        end_timestamp=started + datetime.timedelta(seconds=90),
        current_node=0,
        task_status={"goto": 2},
    )

    response = api.get("/mission/m1")

    assert response.status_code == 200
    status = response.json()["status"]
    assert status == {
        "state": "FAILED",
        "current_node": 0,
        "node_status": {
            "root": {"state": "FAILED", "error_msg": None},
            "goto": {"state": "PENDING", "error_msg": None},
        },
        "task_status": {"goto": 2},
        "start_timestamp": "2024-05-01T12:00:00Z",
        "end_timestamp": "2024-05-01T12:01:30Z",
        "failure_reason": "Mission timed out",
        "failure_category": "TIMEOUT",
        "waiting_reason": None,
        "assignment": [],
    }


def test_missing_mission_is_400_with_the_reference_message(api):
    response = api.get("/mission/nothing")

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "mission" with name "nothing"'}


def test_missions_have_no_put(api):
    MissionFactory(name="m1")

    assert api.put("/mission/m1", {"robot": "x"}).status_code == 405
