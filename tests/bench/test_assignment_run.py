"""`bench.assignment_run` (bench/README.md, "Assignment"): one run binds a small burst, and leaves nothing."""

import pytest

from bench import assignment_run
from missions.models import Mission
from robots.models import Robot

pytestmark = pytest.mark.django_db


def test_a_run_binds_every_mission_of_the_burst_and_removes_its_robots_and_missions() -> None:
    wall, cpu = assignment_run.run(size=5, repeats=1)

    assert wall > 0 and cpu > 0
    assert not Mission.objects.filter(name__startswith=assignment_run.PREFIX).exists()
    assert not Robot.objects.filter(name__startswith=assignment_run.PREFIX).exists()
