"""Compatibility rules through the real step (PostgreSQL, Redis): learned, recorded on the robot, applied
to what goes on the wire at once."""

from datetime import timedelta

import orjson
import pytest

from missions.robot_step import robot_step
from robots import livestate
from robots.models import InstantAction, Robot
from robots.services import instant_action
from tests.dispatch.test_compatibility import LIB_1_4_REJECTION, lib_1_4_no_order_to_cancel
from tests.missions.test_robot_step import NOW, MakeRobot, put_state
from vda5050.models import ActionType
from vda5050.topics import Topic

pytestmark = pytest.mark.django_db(transaction=True)


def instant_action_payloads(robot: Robot, *, after: float) -> list[dict]:
    """The instant actions messages a step puts on the wire, marked published (as the publisher does)."""
    outcome = robot_step(name=robot.name, now=NOW + timedelta(seconds=after))
    livestate.claim_published(robot.name, [(m.topic.value, m.header_id) for m in outcome.wire])
    return [orjson.loads(m.payload) for m in outcome.wire if m.topic == Topic.INSTANT_ACTIONS]


def test_a_robot_that_rejects_actions_is_switched_to_the_legacy_key_and_gets_its_actions_again(
    make_robot: MakeRobot,
) -> None:
    robot = make_robot(prefix="legacy")
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    [first] = instant_action_payloads(robot, after=0.0)  # the factsheet request robot_create queued
    assert "actions" in first and "instantActions" not in first

    put_state(robot, header_id=2, errors=[LIB_1_4_REJECTION])
    [again] = instant_action_payloads(robot, after=1.0)

    assert "actions" not in again
    assert [a["actionId"] for a in again["instantActions"]] == [a["actionId"] for a in first["actions"]]
    assert again["headerId"] == first["headerId"] + 1
    stored = Robot.objects.get(name=robot.name)
    assert (stored.instant_actions_key, stored.instant_actions_key_source) == ("instantActions", "LEARNED")
    [rule] = stored.compatibility_rules
    assert rule["rule"] == "legacy_instant_actions_key"
    assert "#/instantActions" in rule["reason"]


def test_an_operators_key_is_kept_whatever_the_robot_says(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="legacy", vda5050={"instant_actions_key": "actions"})
    Robot.objects.filter(name=robot.name).update(online=True)
    put_state(robot, header_id=1)
    instant_action_payloads(robot, after=0.0)

    put_state(robot, header_id=2, errors=[LIB_1_4_REJECTION])

    assert instant_action_payloads(robot, after=1.0) == []
    stored = Robot.objects.get(name=robot.name)
    assert (stored.instant_actions_key, stored.instant_actions_key_source) == ("actions", "OPERATOR")
    assert stored.compatibility_rules == []


def refused_cancel(robot: Robot, header_id: int) -> InstantAction:
    """A cancelOrder the robot was sent, and a state in which it refuses it as vda-5050-lib 1.4.0 does:
    an error naming it, no action state."""
    cancel = instant_action(robot.name, ActionType.CANCEL_ORDER)
    cancel.sent_at, cancel.send_count = NOW, 1
    cancel.save(force_insert=True)
    put_state(robot, header_id=header_id, errors=[lib_1_4_no_order_to_cancel(cancel.action_id)])
    return cancel


def test_a_cancel_refused_only_by_an_error_is_stored_failed_and_the_rule_recorded_once(
    make_robot: MakeRobot,
) -> None:
    robot = make_robot(prefix="refuse")
    Robot.objects.filter(name=robot.name).update(online=True)
    first = refused_cancel(robot, header_id=1)
    robot_step(name=robot.name, now=NOW + timedelta(seconds=1))
    second = refused_cancel(robot, header_id=2)
    robot_step(name=robot.name, now=NOW + timedelta(seconds=2))

    assert {a.status for a in InstantAction.objects.filter(pk__in=[first.pk, second.pk])} == {"FAILED"}
    stored = Robot.objects.get(name=robot.name)
    [rule] = stored.compatibility_rules
    assert rule["rule"] == "cancel_refused_by_error_only"
    assert (rule["reason"], rule["applied_at"]) == (
        "instant action is not executable: no active order to be canceled",
        (NOW + timedelta(seconds=1)).isoformat(),
    )
    assert (stored.instant_actions_key, stored.instant_actions_key_source) == ("actions", "DEFAULT")
