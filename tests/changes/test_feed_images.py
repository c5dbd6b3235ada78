"""The change feed records what the API shows (migrations changes 0003, 0004): a row's image leaves out the
columns only the dispatch core reads, and a write of those alone records nothing. Real PostgreSQL and Redis,
the step's own path, outside a test transaction (the feed's rows are written by triggers at commit's pace)."""

import importlib
import re

import pytest
from django.db import connection
from django.utils import timezone

from changes.choices import ChangeKind
from changes.models import Change
from missions.models import Mission
from missions.robot_step import robot_step
from missions.services import mission_orders_accepted
from robots.models import Robot
from stations.models import Station
from tests.factories import StationFactory, ZoneSetFactory
from tests.missions.test_robot_step import create, put_state
from vda5050.models import OrderContent
from zones.models import ZoneSet

pytestmark = pytest.mark.django_db(transaction=True)

UNSHOWN = importlib.import_module("changes.migrations.0013_robot_responses_header_id_unshown").UNSHOWN
ROBOT_UNSHOWN = UNSHOWN[Robot._meta.db_table][1]
MISSION_UNSHOWN = UNSHOWN[Mission._meta.db_table][1]
STATIONS_IN_FEED = importlib.import_module("changes.migrations.0005_stations")
STATION_UNSHOWN = STATIONS_IN_FEED.UNSHOWN[Station._meta.db_table][1]
ZONE_SETS_IN_FEED = importlib.import_module("changes.migrations.0008_zone_sets")
ZONE_SET_UNSHOWN = ZONE_SETS_IN_FEED.UNSHOWN[ZoneSet._meta.db_table][1]


def images(kind: str, name: str) -> list[dict]:
    return [c.image for c in Change.objects.filter(kind=kind, name=name).order_by("id")]


@pytest.fixture
def robot(make_robot) -> Robot:
    created = make_robot(prefix="feed")
    Robot.objects.filter(name=created.name).update(online=True)
    put_state(created, header_id=1)
    return created


def test_a_step_that_sends_an_order_records_the_mission_and_not_the_robots_outbox(robot: Robot) -> None:
    robot_before = len(images(ChangeKind.ROBOT, robot.name))
    create("m1", robot)

    outcome = robot_step(name=robot.name)

    assert [m for m in outcome.messages if isinstance(m.content, OrderContent)]
    stored = Robot.objects.get(name=robot.name)
    assert stored.outbox and stored.next_order_header_id > 0  # written, in the step's transaction
    # The robot's state changed too (IDLE to ON_TASK): that, in a write of its own, is all that is recorded.
    [on_task] = images(ChangeKind.ROBOT, robot.name)[robot_before:]
    assert on_task["state"] == "ON_TASK"
    assert [image["state"] for image in images(ChangeKind.MISSION, "m1")] == ["PENDING", "RUNNING"]


def test_an_order_the_robot_took_records_nothing(robot: Robot) -> None:
    create("m1", robot)
    [order] = [m.content for m in robot_step(name=robot.name).messages if isinstance(m.content, OrderContent)]
    recorded = len(images(ChangeKind.MISSION, "m1"))

    mission_orders_accepted(orders={robot.name: (order.order_id, order.order_update_id)})

    assert Mission.objects.get(name="m1").order_accepted is True
    assert len(images(ChangeKind.MISSION, "m1")) == recorded


def test_images_leave_out_the_unshown_columns_and_a_shown_change_is_recorded(robot: Robot) -> None:
    create("m1", robot)
    robot_step(name=robot.name)
    Robot.objects.filter(name=robot.name).update(battery_critical_level=7.0)
    Mission.objects.filter(name="m1").delete()

    robot_images, mission_images = images(ChangeKind.ROBOT, robot.name), images(ChangeKind.MISSION, "m1")
    assert robot_images[-1]["battery_critical_level"] == 7.0
    assert [image["lifecycle"] for image in mission_images][-1] == "DELETED"
    assert mission_images[-1]["state"] == "RUNNING"
    assert all(column not in image for image in robot_images for column in ROBOT_UNSHOWN)
    assert all(column not in image for image in mission_images for column in MISSION_UNSHOWN)


def test_an_idle_robots_last_state_at_records_nothing_and_a_shown_column_records_its_change(
    robot: Robot,
) -> None:
    recorded = len(images(ChangeKind.ROBOT, robot.name))

    Robot.objects.filter(name=robot.name).update(last_state_at=timezone.now(), updated_at=timezone.now())
    assert len(images(ChangeKind.ROBOT, robot.name)) == recorded
    Robot.objects.filter(name=robot.name).update(online=False, last_state_at=timezone.now())
    assert [image["online"] for image in images(ChangeKind.ROBOT, robot.name)[recorded:]] == [False]


def test_every_column_is_unshown_or_compared_by_the_update_trigger(robot: Robot) -> None:
    """A column added later and not compared would have its changes go unrecorded: a migration that adds one
    makes the triggers again (changes 0003's `triggers_sql`)."""
    create("m1", robot)
    robot_step(name=robot.name)
    StationFactory(name="s1")
    ZoneSetFactory(name="z1")
    for model, kind, name, unshown in (
        (Robot, ChangeKind.ROBOT, robot.name, ROBOT_UNSHOWN),
        (Mission, ChangeKind.MISSION, "m1", MISSION_UNSHOWN),
        (Station, ChangeKind.STATION, "s1", STATION_UNSHOWN),
        (ZoneSet, ChangeKind.ZONE_SET, "z1", ZONE_SET_UNSHOWN),
    ):
        table = model._meta.db_table
        with connection.cursor() as cursor:
            columns = {c.name for c in connection.introspection.get_table_description(cursor, table)}
            cursor.execute(
                "SELECT pg_get_triggerdef(oid) FROM pg_trigger WHERE tgname = %s", [f"{table}_changes_update"]
            )
            [definition] = cursor.fetchone()
        assert set(unshown) <= columns
        compared = set(re.findall(r'old\.("?)(\w+)\1', definition))
        assert {column for _, column in compared} == columns - set(unshown)
        assert set(images(kind, name)[-1]) == columns - set(unshown)
