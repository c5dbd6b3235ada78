"""`robots.status.robot_status_write`, the bridge's status flush: a write that takes a robot's battery down to
its low mark asks for the run that sends robots to charge (issue 44), and no other write does."""

import pytest

import robots.status
from robots.models import Robot
from robots.status import robot_status_write
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def runs_asked(monkeypatch: pytest.MonkeyPatch) -> list[None]:
    """The assignment runs the writes asked for (kit.wake.request_assignment), one entry each."""
    asked: list[None] = []
    monkeypatch.setattr(robots.status, "request_assignment", lambda: asked.append(None))
    return asked


def write_batteries(**levels: float) -> set[str]:
    return robot_status_write(
        columns=("battery_level",), rows=[(level, name) for name, level in levels.items()]
    )


def test_a_battery_crossing_the_minimum_asks_for_a_run_once(runs_asked):
    RobotFactory(name="r1", battery_level=40.0, battery_recommended_minimum=30.0)
    RobotFactory(name="r2", battery_level=50.0, battery_recommended_minimum=30.0)

    assert write_batteries(r1=31.0, r2=45.0) == set()
    assert runs_asked == []
    write_batteries(r1=30.0, r2=44.0)  # r1 at its minimum: low
    assert len(runs_asked) == 1
    write_batteries(r1=25.0, r2=43.0)  # already low: nothing new
    assert len(runs_asked) == 1
    assert Robot.objects.get(name="r1").battery_level == 25.0


def test_without_a_minimum_the_critical_level_is_the_mark(runs_asked):
    RobotFactory(name="r1", battery_level=15.0, battery_critical_level=10.0)

    write_batteries(r1=10.5)
    assert runs_asked == []
    write_batteries(r1=10.0)
    assert len(runs_asked) == 1


def test_a_write_without_the_battery_asks_for_nothing(runs_asked):
    RobotFactory(name="r1", battery_level=5.0)

    assert robot_status_write(columns=("pose_x",), rows=[(1.5, "r1")]) == set()
    assert runs_asked == []
    assert Robot.objects.get(name="r1").pose_x == 1.5
