"""Every write records who made it, in the write's own transaction, and operators see the records in the
admin."""

import pytest
from django.contrib.auth.models import User
from django.db import connection
from django.test.utils import CaptureQueriesContext

from access.choices import WriteAction
from access.models import WriteRecord
from missions.models import Mission
from tests.factories import MissionFactory, RobotFactory

pytestmark = pytest.mark.django_db

TREE = [{"name": "go", "route": {"waypoints": [{"x": 1, "y": 2}]}}]
# (method, path, body, the record it leaves), in an order that each write finds what it needs.
WRITES = [
    ("post", "/robot", {"name": "r1"}, (WriteAction.ROBOT_CREATE, "r1")),
    (
        "put",
        "/robot/r1",
        {"heartbeat_timeout": 5, "vda5050": {"version": "2.1.0"}},
        (WriteAction.ROBOT_UPDATE, "r1"),
    ),
    ("post", "/robot/r1/teleop?params=STOP", None, (WriteAction.ROBOT_TELEOP, "r1")),
    (
        "post",
        "/robot/r1/map",
        {"action": "deleteMap", "map_id": "warehouse", "map_version": "1"},
        (WriteAction.ROBOT_MAP, "r1"),
    ),
    (
        "post",
        "/mission",
        {"name": "m1", "robot": "r1", "mission_tree": TREE},
        (WriteAction.MISSION_CREATE, "m1"),
    ),
    (
        "post",
        "/mission/m1/update",
        {"go": {"waypoints": [{"x": 3, "y": 3}]}},
        (WriteAction.MISSION_UPDATE, "m1"),
    ),
    ("post", "/mission/m1/cancel", None, (WriteAction.MISSION_CANCEL, "m1")),
    ("delete", "/mission/m1", None, (WriteAction.MISSION_DELETE, "m1")),
    ("delete", "/robot/r1", None, (WriteAction.ROBOT_DELETE, "r1")),
]


def test_every_write_is_recorded_with_the_token_that_made_it(api, woken):
    for method, path, body, _ in WRITES:
        response = getattr(api, method)(path, body, format="json")
        assert response.status_code == 200, (path, response.content)

    records = list(WriteRecord.objects.order_by("id").values_list("action", "object_name", "actor"))
    assert records == [(action, name, "token:tests") for *_, (action, name) in WRITES]
    assert all(record.at is not None for record in WriteRecord.objects.all())


def test_the_api_answers_keep_the_reference_shapes(api, woken):
    """Recording the actor adds nothing to the bodies clients read."""
    robot = api.post("/robot", {"name": "r1"}, format="json").json()
    mission = api.post("/mission", {"name": "m1", "robot": "r1", "mission_tree": TREE}, format="json").json()

    assert set(robot) == {
        "labels",
        "battery",
        "heartbeat_timeout",
        "switch_teleop",
        "vda5050",
        "name",
        "status",
        "lifecycle",
    }
    assert "actor" not in str(mission) and "created_by" not in str(mission)


def test_a_refused_write_leaves_no_record(api, woken):
    MissionFactory(name="m1", robot="r1")

    duplicate = api.post("/mission", {"name": "m1", "robot": "r1", "mission_tree": TREE}, format="json")
    finished = api.post("/mission/m1/cancel")  # allowed: a queued mission; again: refused
    again = api.post("/mission/m1/cancel")

    assert duplicate.status_code == 400 and finished.status_code == 200 and again.status_code == 400
    assert list(WriteRecord.objects.values_list("action", flat=True)) == [WriteAction.MISSION_CANCEL]


def test_a_mission_and_its_record_are_one_statement(api, woken):
    """mission_create stores both in one INSERT (in autocommit): one cannot exist without the other."""
    with CaptureQueriesContext(connection) as queries:
        api.post("/mission", {"name": "m1", "robot": "r1", "mission_tree": TREE}, format="json")

    [insert] = [query["sql"] for query in queries if WriteRecord._meta.db_table in query["sql"]]
    assert f"INSERT INTO {Mission._meta.db_table}" in insert
    record = WriteRecord.objects.get()
    assert (record.action, record.object_name, record.actor) == (
        WriteAction.MISSION_CREATE,
        "m1",
        "token:tests",
    )


def test_admin_actions_record_the_operator(admin_client, woken):
    RobotFactory(name="r1")
    MissionFactory(name="m1", robot="r1")

    admin_client.post(
        "/admin/missions/mission/", {"action": "cancel_missions", "_selected_action": ["m1"]}, follow=True
    )
    admin_client.post(
        "/admin/robots/robot/", {"action": "stop_teleop", "_selected_action": ["r1"]}, follow=True
    )

    assert set(WriteRecord.objects.values_list("action", "actor")) == {
        (WriteAction.MISSION_CANCEL, "user:admin"),
        (WriteAction.ROBOT_TELEOP, "user:admin"),
    }


def test_operators_read_the_records_in_the_admin_and_cannot_change_them(admin_client, api, woken):
    api.post("/robot", {"name": "r1"}, format="json")
    record = WriteRecord.objects.get()

    listing = admin_client.get("/admin/access/writerecord/")
    detail = admin_client.get(f"/admin/access/writerecord/{record.pk}/change/")

    assert listing.status_code == 200
    assert "token:tests" in listing.content.decode() and "robot_create" in listing.content.decode()
    assert detail.status_code == 200 and 'name="actor"' not in detail.content.decode()
    assert admin_client.get("/admin/access/writerecord/add/").status_code == 403
    assert (
        admin_client.post(f"/admin/access/writerecord/{record.pk}/delete/", {"post": "yes"}).status_code
        == 403
    )
    assert User.objects.get(username="admin").is_staff
