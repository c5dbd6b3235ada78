"""Writes of the change feed. Its rows themselves are written only by the triggers (migration 0001)."""

from datetime import timedelta

from django.conf import settings
from django.db import connection
from django.utils import timezone

from changes.models import Change, TrimMark

# From the oldest row up to the first one inside the retention window: only the rows to delete are read.
# The mark moves to the newest transaction among them, so a stream asked to resume from a position that
# had not seen it knows it would miss changes (changes.selectors.resume_changes).
TRIM_SQL = f"""
    WITH gone AS (
        DELETE FROM {Change._meta.db_table} WHERE id < coalesce(
            (SELECT id FROM {Change._meta.db_table} WHERE created_at >= %s ORDER BY id LIMIT 1),
            (SELECT max(id) + 1 FROM {Change._meta.db_table})
        )
        RETURNING xid
    ), mark AS (
        INSERT INTO {TrimMark._meta.db_table} (id, xid, trimmed_at)
        SELECT 1, max(xid), now() FROM gone HAVING count(*) > 0
        ON CONFLICT (id) DO UPDATE
            SET xid = greatest({TrimMark._meta.db_table}.xid, EXCLUDED.xid), trimmed_at = EXCLUDED.trimmed_at
    )
    SELECT count(*) FROM gone
"""


def changes_trim() -> int:
    """Delete the changes older than FLEET_CHANGE_RETENTION_SECONDS; returns how many. A connected watcher
    is never that far behind (FLEET_WATCH_QUEUE_LINES drops it first); a stream that would resume from
    before the deleted changes is told to take a new snapshot instead."""
    cutoff = timezone.now() - timedelta(seconds=settings.CHANGE_RETENTION_SECONDS)
    with connection.cursor() as cursor:
        cursor.execute(TRIM_SQL, [cutoff])
        (count,) = cursor.fetchone()
        return count
