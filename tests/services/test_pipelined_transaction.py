"""`fleet.db.pipelined_transaction`: the step's transaction block, against the real PostgreSQL.

Outside a test's transaction (as the bridge and the workers run it), so that what it commits or not is
what another connection would see.
"""

import pytest
from django.db import connection, transaction

from fleet.db import pipelined_transaction
from robots.models import Robot
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db(transaction=True)


def set_battery(name: str, level: float) -> None:
    Robot.objects.filter(name=name).update(battery_level=level)


def stored_battery(name: str) -> float:
    return Robot.objects.get(name=name).battery_level


def test_its_writes_are_committed_before_its_on_commit_hooks_run() -> None:
    robot = RobotFactory(battery_level=10.0)
    seen_by_hook: list[float] = []

    with pipelined_transaction():
        set_battery(robot.name, 55.0)
        transaction.on_commit(lambda: seen_by_hook.append(stored_battery(robot.name)))

    assert seen_by_hook == [55.0]
    assert connection.get_autocommit() and not connection.in_atomic_block


def test_an_error_in_the_block_rolls_its_writes_back() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pytest.raises(RuntimeError), pipelined_transaction():
        set_battery(robot.name, 55.0)
        raise RuntimeError("step failed")

    assert stored_battery(robot.name) == 10.0


def test_a_block_marked_for_rollback_commits_nothing() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pipelined_transaction():
        set_battery(robot.name, 55.0)
        transaction.set_rollback(True)

    assert stored_battery(robot.name) == 10.0


def test_inside_a_callers_transaction_its_writes_end_with_the_callers() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pytest.raises(RuntimeError), transaction.atomic():
        with pipelined_transaction():
            set_battery(robot.name, 55.0)
        raise RuntimeError("the caller fails after the block")

    assert stored_battery(robot.name) == 10.0
