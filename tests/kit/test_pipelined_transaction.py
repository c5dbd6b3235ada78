"""`kit.db.pipelined_transaction`: the step's transaction block, against the real PostgreSQL.

Outside a test's transaction (as the bridge and the workers run it), so that what it commits or not is
what another connection would see.
"""

import pytest
from django.db import DataError, connection, transaction
from psycopg.pq import TransactionStatus

from kit.db import pipelined_transaction
from robots.models import Robot
from tests.database import other_connection
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db(transaction=True)


def set_battery(name: str, level: float) -> None:
    Robot.objects.filter(name=name).update(battery_level=level)


def stored_battery(name: str) -> float:
    return Robot.objects.get(name=name).battery_level


def battery_seen_by_another_connection(name: str) -> float:
    sql = f"SELECT battery_level FROM {Robot._meta.db_table} WHERE name = %s"
    with other_connection() as other:
        return other.execute(sql, [name]).fetchone()[0]


def connection_is_back_in_autocommit() -> bool:
    return (
        connection.get_autocommit()
        and not connection.in_atomic_block
        and connection.connection.pgconn.transaction_status == TransactionStatus.IDLE
    )


def test_its_writes_are_committed_and_seen_by_other_connections() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pipelined_transaction():
        set_battery(robot.name, 55.0)
        assert battery_seen_by_another_connection(robot.name) == 10.0  # not yet committed

    assert battery_seen_by_another_connection(robot.name) == 55.0
    assert connection_is_back_in_autocommit()


def test_an_error_in_the_block_rolls_its_writes_back() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pytest.raises(RuntimeError), pipelined_transaction():
        set_battery(robot.name, 55.0)
        raise RuntimeError("step failed")

    assert stored_battery(robot.name) == 10.0
    assert connection_is_back_in_autocommit()


@pytest.mark.parametrize(
    "read_in_block",
    [
        pytest.param(True, id="read_in_the_block"),
        pytest.param(False, id="reported_at_the_sync"),  # its result is read after the block
    ],
)
def test_a_failed_statement_raises_djangos_error_rolls_back_and_leaves_the_connection_usable(
    read_in_block: bool,
) -> None:
    robot = RobotFactory(battery_level=10.0)

    with pytest.raises(DataError), pipelined_transaction():  # Django's, not psycopg's
        set_battery(robot.name, 55.0)
        with connection.cursor() as cursor:
            cursor.execute("SELECT 1 / 0")
            if read_in_block:
                cursor.fetchone()

    assert connection_is_back_in_autocommit()
    assert stored_battery(robot.name) == 10.0


def test_inside_a_callers_transaction_its_writes_end_with_the_callers() -> None:
    robot = RobotFactory(battery_level=10.0)

    with pytest.raises(RuntimeError), transaction.atomic():
        with pipelined_transaction():
            set_battery(robot.name, 55.0)
        raise RuntimeError("the caller fails after the block")

    assert stored_battery(robot.name) == 10.0
