"""robots.services, called as the admin, management commands and the API call them."""

import re

import pytest

from kit.api.errors import ObjectError, UsageError
from robots.choices import Lifecycle, TeleopAction
from robots.models import Robot
from robots.services import robot_create, robot_delete, robot_teleop, robot_update_spec
from tests.factories import TEST_ACTOR, MissionFactory, RobotFactory

pytestmark = pytest.mark.django_db


def test_create_with_an_empty_spec_gives_the_defaults(woken):
    robot = robot_create(actor=TEST_ACTOR, name="carter01", prefix=None, spec={})

    stored = Robot.objects.get(name="carter01")
    assert stored == robot
    assert (stored.labels, stored.heartbeat_timeout, stored.battery_critical_level) == ([], 30.0, 10.0)
    assert stored.serial_number == "carter01"
    assert woken == ["carter01"]


def test_create_maps_the_api_shaped_spec_to_the_model():
    robot = robot_create(
        actor=TEST_ACTOR,
        name=None,
        prefix="amr",
        spec={
            "labels": ["a"],
            "battery": {"critical_level": 5.0, "recommended_minimum": 20.0, "recommended_maximum": 95.0},
            "heartbeat_timeout": 3.0,
            "switch_teleop": True,
            "vda5050": {"manufacturer": "Acme", "version": "2.1.0"},
        },
    )

    stored = Robot.objects.get(name=robot.name)
    assert stored.name.startswith("amr-")
    assert (stored.battery_critical_level, stored.battery_recommended_minimum) == (5.0, 20.0)
    assert stored.battery_recommended_maximum == 95.0
    assert (stored.heartbeat_timeout, stored.switch_teleop, stored.labels) == (3.0, True, ["a"])
    assert (stored.manufacturer, stored.protocol_version, stored.serial_number) == (
        "Acme",
        "2.1.0",
        robot.name,
    )


def test_create_registers_one_step_and_one_assignment_request_for_after_commit(
    django_capture_on_commit_callbacks,
):
    with django_capture_on_commit_callbacks() as callbacks:
        robot_create(actor=TEST_ACTOR, name="carter01", prefix=None, spec={})

    assert len(callbacks) == 2  # its step, and an assignment run: it may be what unbound missions wait for


def test_a_refused_create_wakes_nothing(django_capture_on_commit_callbacks):
    RobotFactory(name="carter01")

    with django_capture_on_commit_callbacks() as callbacks, pytest.raises(ObjectError):
        robot_create(actor=TEST_ACTOR, name="carter01", prefix=None, spec={})

    assert callbacks == []


@pytest.mark.parametrize(
    ("name", "spec", "message_part"),
    [
        ("carter 01", {}, "invalid"),
        ("carter01\n", {}, "invalid"),
        ("c" * 101, {}, "longer than 100"),
        ("carter01", {"colour": "red"}, "Unknown robot spec fields ['colour']"),
    ],
)
def test_create_refuses_bad_input_from_any_caller(name, spec, message_part):
    with pytest.raises(UsageError, match=re.escape(message_part)):
        robot_create(actor=TEST_ACTOR, name=name, prefix=None, spec=spec)

    assert not Robot.objects.exists()


def test_update_spec_replaces_the_whole_spec(woken):
    robot = RobotFactory(
        name="carter01", labels=["x"], heartbeat_timeout=3.0, manufacturer="Acme", online=True
    )

    updated = robot_update_spec(actor=TEST_ACTOR, robot=robot, spec={"switch_teleop": True})

    stored = Robot.objects.get(name="carter01")
    assert updated == stored
    assert (stored.labels, stored.heartbeat_timeout, stored.switch_teleop) == ([], 30.0, True)
    assert stored.manufacturer == "RobotCompany"
    assert stored.online is True
    assert woken == ["carter01"]


def test_update_spec_of_a_robot_removed_meanwhile_is_the_reference_error():
    robot = RobotFactory(name="carter01")
    Robot.objects.filter(name="carter01").delete()

    with pytest.raises(ObjectError, match="Could not find object carter01"):
        robot_update_spec(actor=TEST_ACTOR, robot=robot, spec={})


def test_delete_returns_none_once_the_robot_is_removed(woken):
    robot = RobotFactory(name="carter01")

    assert robot_delete(actor=TEST_ACTOR, robot=robot) is None
    assert not Robot.objects.exists()
    assert woken == ["carter01"]


def test_delete_of_a_robot_running_a_mission_returns_it_pending_delete():
    robot = RobotFactory(name="carter01", state="ON_TASK")
    MissionFactory(robot="carter01", running=True)

    remaining = robot_delete(actor=TEST_ACTOR, robot=robot)

    assert remaining is not None
    assert remaining.lifecycle == Lifecycle.PENDING_DELETE
    assert Robot.objects.get(name="carter01").lifecycle == Lifecycle.PENDING_DELETE


def test_teleop_reads_the_state_from_the_database_not_the_callers_copy():
    robot = RobotFactory(name="carter01", state="IDLE")
    Robot.objects.filter(name="carter01").update(state="CHARGING")

    with pytest.raises(UsageError, match="CHARGING"):
        robot_teleop(actor=TEST_ACTOR, robot=robot, action=TeleopAction.START)


def test_teleop_start_and_stop(woken):
    robot = RobotFactory(name="carter01", state="ON_TASK")

    assert robot_teleop(actor=TEST_ACTOR, robot=robot, action=TeleopAction.START).switch_teleop is True
    assert robot_teleop(actor=TEST_ACTOR, robot=robot, action=TeleopAction.STOP).switch_teleop is False
    assert Robot.objects.get(name="carter01").switch_teleop is False
    assert woken == ["carter01", "carter01"]
