"""`manage.py seed_robots`: robots with the default spec, created once however often it runs."""

from io import StringIO

import pytest
from django.core.management import CommandError, call_command

from robots.models import Robot
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db


def seed(*args: str) -> list[str]:
    out = StringIO()
    call_command("seed_robots", *args, stdout=out)
    return out.getvalue().splitlines()


def test_count_and_prefix_create_numbered_robots_with_the_default_spec(woken: list[str]):
    output = seed("--count", "3", "--prefix", "carter")

    robots = list(Robot.objects.order_by("name"))
    assert [robot.name for robot in robots] == ["carter01", "carter02", "carter03"]
    assert {
        (robot.serial_number == robot.name, robot.heartbeat_timeout, robot.pose_x) for robot in robots
    } == {(True, 30.0, 0.0)}
    assert woken == ["carter01", "carter02", "carter03"]
    assert output == ["Created carter01.", "Created carter02.", "Created carter03.", "3 created, 0 skipped."]


def test_numbers_get_as_many_digits_as_the_count_needs():
    seed("--count", "100", "--prefix", "r")

    names = set(Robot.objects.values_list("name", flat=True))
    assert {"r001", "r010", "r100"} <= names
    assert len(names) == 100


def test_explicit_names():
    output = seed("dock-bot", "carter01", "dock-bot")

    assert sorted(Robot.objects.values_list("name", flat=True)) == ["carter01", "dock-bot"]
    assert output[-1] == "2 created, 0 skipped."


def test_running_again_changes_nothing():
    seed("--count", "2", "--prefix", "carter")
    before = list(Robot.objects.order_by("name").values())

    output = seed("--count", "2", "--prefix", "carter")

    assert list(Robot.objects.order_by("name").values()) == before
    assert output == [
        "Skipped carter01: already exists.",
        "Skipped carter02: already exists.",
        "0 created, 2 skipped.",
    ]


def test_existing_robots_are_skipped_and_the_rest_created():
    RobotFactory(name="carter02", heartbeat_timeout=5.0)

    output = seed("--count", "3")

    assert sorted(Robot.objects.values_list("name", "heartbeat_timeout")) == [
        ("carter01", 30.0),
        ("carter02", 5.0),
        ("carter03", 30.0),
    ]
    assert output[-1] == "2 created, 1 skipped."


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((), "Give robot names or --count N."),
        (("carter01", "--count", "2"), "Give either robot names or --count, not both."),
        (("--count", "0"), "--count must be at least 1."),
        (("bad name",), "Robot name 'bad name' is invalid"),
    ],
)
def test_refuses_unclear_requests(args: tuple[str, ...], message: str):
    with pytest.raises(CommandError, match=message):
        seed(*args)

    assert not Robot.objects.exists()
