"""Reads of the change feed for the watch streams (changes.stream).

A feed position is a PostgreSQL snapshot (pg_snapshot as text): the changes a watcher has had are exactly
those committed in it. Each read runs in a REPEATABLE READ transaction and takes the changes its own
snapshot sees and the previous position did not, so a change committed late with a lower id is never
skipped, and none is read twice.
"""

from collections.abc import Iterator
from contextlib import contextmanager

from django.db import connection, transaction
from django.db.models import Model, QuerySet
from django.db.models.expressions import RawSQL

from changes.models import Change


@contextmanager
def _at_feed_position() -> Iterator[str]:
    """A REPEATABLE READ transaction and the feed position of its snapshot: what it reads is exactly what
    that position has."""
    with transaction.atomic():
        with connection.cursor() as cursor:
            cursor.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ")
            cursor.execute("SELECT pg_current_snapshot()::text")
            (position,) = cursor.fetchone()
        yield position


def watch_snapshot(*, queryset: QuerySet) -> tuple[str, list[Model]]:
    """The objects `queryset` selects now and the feed position they are at: a stream goes on from exactly
    there, with no change in a gap and none twice."""
    with _at_feed_position() as position:
        return position, list(queryset)


def watch_changes(*, reads: list[tuple[str, QuerySet, str]]) -> tuple[str, list[list[Model]]]:
    """The feed position now and, for each (kind, queryset, since), the objects of `kind` as each change
    committed after `since` left them, those `queryset` selects, in feed order."""
    with _at_feed_position() as position:
        return position, [_changed(kind, queryset, since) for kind, queryset, since in reads]


def _changed(kind: str, queryset: QuerySet, since: str) -> list[Model]:
    """The list endpoint's own query (its filters) runs over the changes' row images, which a CTE named as
    the table stands for."""
    model = queryset.model
    table = connection.ops.quote_name(model._meta.db_table)
    ordered = queryset.order_by().annotate(change_id=RawSQL(f"{table}.change_id", [])).order_by("change_id")
    sql, params = ordered.query.sql_with_params()
    images = f"""
        WITH {table} AS (
            SELECT c.id AS change_id, r.*
            FROM {Change._meta.db_table} c
            CROSS JOIN LATERAL jsonb_populate_record(NULL::{table}, c.image) r
            WHERE c.kind = %s AND c.xid >= pg_snapshot_xmin(%s::pg_snapshot)
                AND NOT pg_visible_in_snapshot(c.xid, %s::pg_snapshot)
        )
    """
    return list(model.objects.raw(images + sql, [kind, since, since, *params]))
