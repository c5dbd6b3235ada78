"""Zone sets reach 3.0 robots through their steps (`missions.robot_step`, `dispatch.zone_sets`), against the
real PostgreSQL and Redis: the `zoneSet` message on its own topic and headerId counter, then `enableZoneSet`;
`deleteZoneSet` for a set the fleet disabled; nothing for 2.x robots or robots without zone support; and the
sweep finds the robots whose sets are due."""

from collections.abc import Callable
from datetime import timedelta

import orjson
import pytest
from django.conf import settings

from missions.robot_step import StepOutcome, robot_step
from missions.selectors import robots_due_for_step
from robots.models import InstantAction, Robot
from tests.dispatch.builders import robot_state
from tests.factories import TEST_ACTOR
from tests.missions.test_robot_step import NOW, instant_actions, put_state
from tests.vda5050.schemas import validate_message
from tests.zones.bodies import zone_set
from vda5050.models import MapStatus, State, ZoneSetContent, ZoneSetState
from vda5050.topics import Topic
from zones.models import ZoneSet
from zones.services import zone_set_create, zone_set_disable, zone_set_enable

pytestmark = pytest.mark.django_db(transaction=True)

RESEND = settings.DISPATCH_INSTANT_ACTION_RESEND_SECONDS


@pytest.fixture
def enabled_set() -> ZoneSet:
    spec = zone_set(name="floor1-v1")
    spec.pop("name")
    created = zone_set_create(
        actor=TEST_ACTOR, name="floor1-v1", prefix=None, spec={"description": "", **spec}
    )
    return zone_set_enable(actor=TEST_ACTOR, zone_set=created)


def zone_robot(make_robot: Callable[..., Robot], *, version: str = "3.0.0", zones: bool = True) -> Robot:
    """An online robot of `version` whose factsheet lists zone types (if `zones`), on map `map`."""
    robot = make_robot(prefix="zones", vda5050={"version": version})
    Robot.objects.filter(name=robot.name).update(
        online=True, supported_zones=["RELEASE"] if zones else [], pose_map_id="map"
    )
    InstantAction.objects.filter(robot=robot).delete()  # the factsheet request: its steps are not ours
    put_state(robot, header_id=1)
    return robot


def holding(*held: tuple[str, MapStatus]) -> State:
    return robot_state().model_copy(
        update={"zone_sets": [ZoneSetState(zone_set_id=i, map_id="map", zone_set_status=s) for i, s in held]}
    )


def step(robot: Robot, *, after: float = 0.0) -> StepOutcome:
    return robot_step(name=robot.name, now=NOW + timedelta(seconds=after))


def zone_sets_sent(outcome: StepOutcome) -> list[ZoneSetContent]:
    return [m.content for m in outcome.messages if isinstance(m.content, ZoneSetContent)]


def zone_actions(outcome: StepOutcome) -> list[tuple[str, dict[str, str]]]:
    return [
        (a.action_type, {p.key: p.value for p in a.action_parameters or ()})
        for a in instant_actions(outcome)
        if a.action_type.endswith("ZoneSet")
    ]


def test_a_3_0_robot_gets_the_zone_set_message_on_its_own_topic_once(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet
) -> None:
    robot = zone_robot(make_robot)

    outcome = step(robot)

    [content] = zone_sets_sent(outcome)
    assert (content.zone_set.zone_set_id, content.zone_set.map_id) == ("floor1-v1", "map")
    assert [zone.zone_id for zone in content.zone_set.zones] == ["aisle"]
    [wire] = [m for m in outcome.wire if m.topic == Topic.ZONE_SET]
    assert wire.header_id == 0
    validate_message("zoneSet", "3.0.0", orjson.loads(wire.payload))
    stored = Robot.objects.get(name=robot.name)
    assert stored.next_zone_set_header_id == 1
    assert stored.zone_set_moves == {"floor1-v1": "zoneSet"}
    # Not twice while it may be on its way; again once the resend period passed without the robot holding it.
    assert zone_sets_sent(step(robot, after=1)) == []
    assert len(zone_sets_sent(step(robot, after=RESEND + 1))) == 1
    assert Robot.objects.get(name=robot.name).next_zone_set_header_id == 2


def test_a_set_the_robot_holds_disabled_is_enabled_then_the_moves_are_forgotten(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet
) -> None:
    robot = zone_robot(make_robot)
    step(robot)
    put_state(robot, header_id=2, state=holding(("floor1-v1", MapStatus.DISABLED)))

    outcome = step(robot, after=1)

    assert zone_sets_sent(outcome) == []
    assert zone_actions(outcome) == [("enableZoneSet", {"zoneSetId": "floor1-v1"})]
    put_state(robot, header_id=3, state=holding(("floor1-v1", MapStatus.ENABLED)))
    assert zone_actions(step(robot, after=2)) == []
    assert Robot.objects.get(name=robot.name).zone_set_moves == {}


def test_a_set_the_fleet_disabled_is_deleted_where_a_robot_holds_it(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet
) -> None:
    robot = zone_robot(make_robot)
    put_state(robot, header_id=2, state=holding(("floor1-v1", MapStatus.ENABLED)))
    assert zone_actions(step(robot)) == []

    zone_set_disable(actor=TEST_ACTOR, zone_set=enabled_set)

    assert zone_actions(step(robot, after=1)) == [("deleteZoneSet", {"zoneSetId": "floor1-v1"})]


@pytest.mark.parametrize(("version", "zones"), [("2.1.0", True), ("3.0.0", False)])
def test_robots_that_cannot_take_zone_sets_get_nothing(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet, version: str, zones: bool
) -> None:
    robot = zone_robot(make_robot, version=version, zones=zones)

    outcome = step(robot)

    assert (zone_sets_sent(outcome), zone_actions(outcome)) == ([], [])
    assert Robot.objects.get(name=robot.name).next_zone_set_header_id == 0


def test_a_robot_offline_gets_its_set_once_back(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet
) -> None:
    robot = zone_robot(make_robot)
    Robot.objects.filter(name=robot.name).update(online=False)
    assert zone_sets_sent(step(robot)) == []

    Robot.objects.filter(name=robot.name).update(online=True)

    assert len(zone_sets_sent(step(robot, after=1))) == 1


def test_the_sweep_steps_robots_whose_zone_sets_are_due(
    make_robot: Callable[..., Robot], enabled_set: ZoneSet
) -> None:
    robot = zone_robot(make_robot)
    old = zone_robot(make_robot, version="2.1.0")
    assert robot.name in robots_due_for_step(now=NOW)

    step(robot)  # the zoneSet message: not due again before the resend period
    assert robot.name not in robots_due_for_step(now=NOW + timedelta(seconds=1))
    assert robot.name in robots_due_for_step(now=NOW + timedelta(seconds=RESEND))

    Robot.objects.filter(name=robot.name).update(
        zone_sets=[{"map_id": "map", "zone_set_id": "floor1-v1", "zone_set_status": "ENABLED"}]
    )
    assert robot.name not in robots_due_for_step(now=NOW + timedelta(seconds=RESEND))
    assert old.name not in robots_due_for_step(now=NOW + timedelta(seconds=RESEND))
