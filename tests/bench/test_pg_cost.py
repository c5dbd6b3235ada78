"""bench.pg_cost against the test database and Redis: each cycle runs a whole mission through the step's
path, and the counts per mission are PostgreSQL's own."""

import pytest

from bench.pg_cost import measure
from missions.models import Mission

pytestmark = pytest.mark.django_db(transaction=True)


def test_each_mission_is_created_started_taken_and_ended_and_counted() -> None:
    cost = measure(missions=12, robots=3)

    assert Mission.objects.filter(state="COMPLETED").count() == 12  # each measured cycle ended one
    assert cost.mission_updates == 3.0  # started, its order taken, ended
    assert cost.feed_rows == 3.0  # created, started, ended: taking the order shows nothing new
    assert cost.wal_bytes > 0 and cost.client_cpu_ms > 0  # the backend's CPU, in 10-ms ticks, may read 0
