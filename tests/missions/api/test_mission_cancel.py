"""POST /mission/{name}/cancel in each mission state."""

import pytest

from missions.models import Mission
from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db


def test_a_queued_mission_is_canceled_at_once(api, woken):
    MissionFactory(name="m1", robot="carter01")

    response = api.post("/mission/m1/cancel")

    assert response.status_code == 200
    assert response.json() == {"detail": "Mission m1 will be canceled."}
    status = api.get("/mission/m1").json()["status"]
    assert status["state"] == "CANCELED"
    assert status["failure_category"] == "CANCELED"
    assert status["end_timestamp"] is not None
    assert status["start_timestamp"] is None
    assert status["node_status"]["root"] == {"state": "CANCELED", "error_msg": None}
    assert status["node_status"]["goto"] == {"state": "PENDING", "error_msg": None}
    assert api.get("/mission/m1").json()["needs_canceled"] is True
    assert woken == ["carter01"]


def test_a_running_mission_is_marked_for_the_engine_to_cancel(api, woken):
    MissionFactory(name="m1", robot="carter01", running=True)

    response = api.post("/mission/m1/cancel")

    assert response.json() == {"detail": "Mission m1 will be canceled."}
    mission = Mission.objects.get(name="m1")
    assert (mission.state, mission.needs_canceled, mission.end_timestamp) == ("RUNNING", True, None)
    assert woken == ["carter01"]


def test_canceling_a_running_mission_twice_is_accepted(api):
    MissionFactory(name="m1", running=True, needs_canceled=True)

    assert api.post("/mission/m1/cancel").status_code == 200


@pytest.mark.parametrize(
    ("trait", "message"),
    [
        ("canceled", "Mission m1 is already canceled."),
        ("completed", "Completed mission m1 can't be canceled."),
        ("failed", "Failed mission m1 can't be canceled."),
    ],
)
def test_a_finished_mission_cannot_be_canceled(api, woken, trait, message):
    MissionFactory(name="m1", **{trait: True})
    before = Mission.objects.get(name="m1")

    response = api.post("/mission/m1/cancel")

    assert response.status_code == 400
    assert response.json() == {"message": message, "error_code": "USAGE"}
    after = Mission.objects.get(name="m1")
    assert (after.state, after.end_timestamp, after.needs_canceled) == (
        before.state,
        before.end_timestamp,
        before.needs_canceled,
    )
    assert woken == []


def test_missing_mission_is_400_with_the_reference_message(api):
    response = api.post("/mission/nothing/cancel")

    assert response.status_code == 400
    assert response.json() == {"detail": 'Did not find "mission" with name "nothing"'}
