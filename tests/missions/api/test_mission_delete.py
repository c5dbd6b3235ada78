"""DELETE /mission/{name} in each mission state."""

import pytest

from missions.models import Mission
from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db


@pytest.mark.parametrize("trait", [None, "completed", "failed", "canceled"])
def test_a_mission_that_is_not_running_is_removed_at_once(api, woken, trait):
    MissionFactory(name="m1", robot="carter01", **({trait: True} if trait else {}))

    response = api.delete("/mission/m1")

    assert response.status_code == 200
    assert response.json() == {"detail": "m1 is PENDING_DELETE"}
    assert not Mission.objects.filter(name="m1").exists()
    assert api.get("/mission/m1").status_code == 400
    assert woken == ["carter01"]


def test_a_running_mission_is_canceled_and_stays_pending_delete(api, woken):
    MissionFactory(name="m1", robot="carter01", running=True)

    response = api.delete("/mission/m1")

    assert response.json() == {"detail": "m1 is PENDING_DELETE"}
    body = api.get("/mission/m1").json()
    assert (body["lifecycle"], body["needs_canceled"], body["status"]["state"]) == (
        "PENDING_DELETE",
        True,
        "RUNNING",
    )
    assert woken == ["carter01"]


def test_missing_mission_is_400_with_the_reference_message(api):
    response = api.delete("/mission/nothing")

    assert response.status_code == 400
    assert response.json() == {"detail": "Could not find object nothing"}
