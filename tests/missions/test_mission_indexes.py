"""The missions table's indexes: each serves a query, because each costs an entry at most updates of a
mission (migration 0006)."""

import pytest
from django.db import connection

from missions.choices import Lifecycle
from missions.models import Mission
from tests.factories import MissionFactory

pytestmark = pytest.mark.django_db


def _indexes() -> dict[str, str]:
    with connection.cursor() as cursor:
        cursor.execute("SELECT indexname, indexdef FROM pg_indexes WHERE tablename = 'missions_mission'")
        return dict(cursor.fetchall())


def test_the_missions_table_has_only_the_indexes_its_queries_use() -> None:
    assert set(_indexes()) == {
        "missions_mission_pkey",  # by name: the API, the steps' updates
        "mission_queue_idx",  # a robot's running and queued missions: every step; GET /mission?robot=
        "mission_state_idx",  # GET /mission?state=, the admin's filter
        "mission_start_idx",  # GET /mission?started_after=, most_recent
        "mission_lifecycle_idx",  # the admin's filter for deleting missions
        "mission_pending_deadline_idx",  # beat's sweep
        "mission_unnoticed_idx",  # beat's sweep
        "mission_running_idx",  # beat's sweep
        "mission_unbound_idx",  # assignment's unbound queue, GET /mission?unbound=true
    }


def test_the_lifecycle_index_holds_only_deleting_missions_and_serves_the_admins_filter() -> None:
    assert "WHERE (NOT ((lifecycle)::text = 'ALIVE'::text))" in _indexes()["mission_lifecycle_idx"]
    MissionFactory.create_batch(3)
    MissionFactory(name="m-leaving", lifecycle=Lifecycle.PENDING_DELETE)
    deleting = Mission.objects.filter(lifecycle=Lifecycle.PENDING_DELETE)

    with connection.cursor() as cursor:
        cursor.execute("SET LOCAL enable_seqscan = off")  # four rows: the planner would read the table
        plan = deleting.explain()

    assert "mission_lifecycle_idx" in plan
    assert [mission.name for mission in deleting] == ["m-leaving"]
