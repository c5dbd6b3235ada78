"""Writes of the change feed. Its rows themselves are written only by the triggers (migration 0001)."""

from datetime import timedelta

from django.conf import settings
from django.db import connection
from django.utils import timezone

from changes.models import Change

# From the oldest row up to the first one inside the retention window: only the rows to delete are read.
TRIM_SQL = f"""
    DELETE FROM {Change._meta.db_table} WHERE id < coalesce(
        (SELECT id FROM {Change._meta.db_table} WHERE created_at >= %s ORDER BY id LIMIT 1),
        (SELECT max(id) + 1 FROM {Change._meta.db_table})
    )
"""


def changes_trim() -> int:
    """Delete the changes older than FLEET_CHANGE_RETENTION_SECONDS; returns how many. A watcher is never
    that far behind (FLEET_WATCH_QUEUE_LINES drops it first), so no stream loses a change to this."""
    cutoff = timezone.now() - timedelta(seconds=settings.CHANGE_RETENTION_SECONDS)
    with connection.cursor() as cursor:
        cursor.execute(TRIM_SQL, [cutoff])
        return cursor.rowcount
