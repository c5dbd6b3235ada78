"""missions.services, called as the admin, the engine's tests and the API call them."""

import re

import pytest

from kit.api.errors import ObjectError, UsageError
from missions.choices import FailureCategory, Lifecycle, MissionState
from missions.models import Mission
from missions.services import mission_cancel, mission_create, mission_delete, mission_update_routes
from tests.factories import TEST_ACTOR, MissionFactory, route_node

pytestmark = pytest.mark.django_db

WAYPOINT = {
    "x": 1.0,
    "y": 2.0,
    "theta": 0.0,
    "map_id": "",
    "allowedDeviationXY": 0.1,
    "allowedDeviationTheta": 0.0,
}


def spec(*mission_tree: dict, **fields) -> dict:
    return {"robot": "carter01", "mission_tree": list(mission_tree), **fields}


def route(**node) -> dict:
    return {"route": {"waypoints": [WAYPOINT]}, **node}


def test_create_stores_the_tree_normalized_and_every_node_pending(woken):
    mission = mission_create(
        actor=TEST_ACTOR,
        name="m1",
        prefix=None,
        spec=spec(route(), {"name": "s", "selector": {}}, route(parent="s")),
    )

    stored = Mission.objects.get(name="m1")
    assert stored.mission_tree == [
        {"name": "0", "parent": "root", "route": {"waypoints": [WAYPOINT]}},
        {"name": "s", "parent": "root", "selector": {}},
        {"name": "2", "parent": "s", "route": {"waypoints": [WAYPOINT]}},
    ]
    assert stored.node_status == {
        name: {"state": "PENDING", "error_msg": None} for name in ("root", "0", "s", "2")
    }
    assert (stored.state, stored.timeout, stored.queue_position) == ("PENDING", 300.0, mission.queue_position)
    assert woken == ["carter01"]


@pytest.mark.parametrize(
    ("earlier", "wakes"),
    [
        pytest.param(None, True, id="none"),
        pytest.param({"robot": "carter02"}, True, id="other_robot"),
        pytest.param({"robot": "carter02", "running": True}, True, id="other_robot_running"),
        pytest.param({"completed": True}, True, id="completed"),
        pytest.param({"failed": True}, True, id="failed"),
        pytest.param({"canceled": True}, True, id="canceled"),
        pytest.param({}, False, id="pending"),
        pytest.param({"running": True}, False, id="running"),
    ],
)
def test_create_wakes_the_robot_unless_queued_behind_an_unfinished_mission(woken, earlier, wakes):
    if earlier is not None:
        MissionFactory(name="earlier", **earlier)

    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec(route()))

    assert woken == (["carter01"] if wakes else [])


def test_a_mission_created_canceled_still_wakes_an_idle_robot(woken):
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec(route(), needs_canceled=True))

    assert woken == ["carter01"]


def test_create_returns_the_stored_row(woken):
    mission = mission_create(
        actor=TEST_ACTOR,
        name="m1",
        prefix=None,
        spec=spec(route(name="go"), timeout=60.0, update_nodes={"go": {"waypoints": [WAYPOINT]}}),
    )

    stored = Mission.objects.get(name="m1")
    assert mission._state.adding is False
    assert {field.name: getattr(mission, field.name) for field in Mission._meta.concrete_fields} == {
        field.name: getattr(stored, field.name) for field in Mission._meta.concrete_fields
    }
    assert mission.created_at <= mission.updated_at


def test_queue_positions_follow_creation_order():
    first = mission_create(actor=TEST_ACTOR, name="a", prefix=None, spec=spec(route()))
    second = mission_create(actor=TEST_ACTOR, name="b", prefix=None, spec=spec(route()))

    assert first.queue_position < second.queue_position


@pytest.mark.parametrize(
    ("fields", "message_part"),
    [
        ({"mission_tree": []}, "Number of nodes"),
        ({"mission_tree": [route(name="bad name")]}, "MissionNode name 'bad name' is invalid"),
        ({"mission_tree": [route(), {"name": "x", "route": None}]}, "Exactly one"),
        ({"robot": "carter/01"}, "Robot name 'carter/01' is invalid"),
    ],
)
def test_create_refuses_bad_trees_from_any_caller(fields, message_part):
    with pytest.raises(UsageError, match=re.escape(message_part)):
        mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec={**spec(route()), **fields})

    assert not Mission.objects.exists()


def test_a_duplicate_name_is_the_reference_error_and_wakes_nothing(django_capture_on_commit_callbacks):
    MissionFactory(name="m1", robot="carter09")

    with django_capture_on_commit_callbacks() as callbacks, pytest.raises(ObjectError) as raised:
        mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec=spec(route()))

    assert raised.value.detail == "Object mission with name m1 already exists"
    assert callbacks == []
    assert list(Mission.objects.values_list("name", "robot")) == [("m1", "carter09")]


def test_cancel_reads_the_state_from_the_database_not_the_callers_copy():
    mission = MissionFactory(name="m1")
    Mission.objects.filter(name="m1").update(state=MissionState.COMPLETED)

    with pytest.raises(UsageError, match=re.escape("Completed mission m1 can't be canceled.")):
        mission_cancel(actor=TEST_ACTOR, mission=mission)


def test_cancel_of_a_queued_mission_ends_it(woken):
    canceled = mission_cancel(actor=TEST_ACTOR, mission=MissionFactory(name="m1", robot="carter07"))

    stored = Mission.objects.get(name="m1")
    assert canceled == stored
    assert (stored.state, stored.failure_category, stored.needs_canceled) == (
        MissionState.CANCELED,
        FailureCategory.CANCELED,
        True,
    )
    assert stored.end_timestamp is not None
    assert woken == ["carter07"]


def test_cancel_of_a_running_mission_leaves_the_ending_to_the_engine():
    mission_cancel(actor=TEST_ACTOR, mission=MissionFactory(name="m1", running=True))

    stored = Mission.objects.get(name="m1")
    assert (stored.state, stored.needs_canceled, stored.failure_category) == (
        MissionState.RUNNING,
        True,
        None,
    )


def test_delete_returns_none_once_removed_and_the_mission_while_it_runs():
    assert mission_delete(actor=TEST_ACTOR, mission=MissionFactory(name="queued")) is None
    running = mission_delete(actor=TEST_ACTOR, mission=MissionFactory(name="running", running=True))

    assert running is not None
    assert (running.lifecycle, running.needs_canceled) == (Lifecycle.PENDING_DELETE, True)
    assert list(Mission.objects.values_list("name", flat=True)) == ["running"]


def test_update_routes_merges_and_returns_the_mission(woken):
    mission = MissionFactory(name="m1", robot="carter03", mission_tree=[route_node("a"), route_node("b")])
    new_a = {"waypoints": [{**WAYPOINT, "x": 9.0}]}

    updated = mission_update_routes(actor=TEST_ACTOR, mission=mission, update_nodes={"a": new_a})
    updated = mission_update_routes(actor=TEST_ACTOR, mission=updated, update_nodes={"b": new_a})

    assert updated.update_nodes == {"a": new_a, "b": new_a}
    assert Mission.objects.get(name="m1").update_nodes == {"a": new_a, "b": new_a}
    assert woken == ["carter03", "carter03"]
