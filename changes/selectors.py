"""Reads of the change feed for the watch streams (changes.stream).

A feed position is a PostgreSQL snapshot (pg_snapshot as text): the changes a watcher has had are exactly
those committed in it. Each read runs in a REPEATABLE READ transaction and takes the changes its own
snapshot sees and the previous position did not, so a change committed late with a lower id is never
skipped, and none is read twice.
"""

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from django.db import connection, transaction
from django.db.models import Model, QuerySet
from django.db.models.expressions import RawSQL

from changes.models import Change, TrimMark

# pg_snapshot's text form, xmin:xmax:xip,xip,... (xid8s, below 2**63 for the next few million years)
POSITION = re.compile(r"\A([0-9]{1,18}):([0-9]{1,18}):((?:[0-9]{1,18}(?:,[0-9]{1,18})*)?)\Z")


class FeedPositionInvalid(ValueError):
    """A position this feed never gave out (a malformed or forged resume id)."""


class FeedPositionExpired(Exception):
    """The feed no longer has every change after this position (or has too many to send at once)."""


@dataclass(frozen=True)
class Span:
    """The changes a read takes: committed after `since`, and, for a stream that resumes in the middle of
    an earlier read, only those of that read (committed in `until`) that came after change `after`."""

    since: str
    until: str | None = None
    after: int = 0


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


def watch_snapshot(*, querysets: list[QuerySet]) -> tuple[str, list[list[Model]]]:
    """The objects each queryset selects now and the feed position they are at: a stream goes on from
    exactly there, with no change in a gap and none twice."""
    with _at_feed_position() as position:
        return position, [list(queryset) for queryset in querysets]


def watch_changes(*, reads: list[tuple[str, QuerySet, str]]) -> tuple[str, list[list[Model]]]:
    """The feed position now and, for each (kind, queryset, since), the objects of `kind` as each change
    committed after `since` left them, those `queryset` selects, in feed order."""
    with _at_feed_position() as position:
        return position, [_changed(kind, queryset, Span(since)) for kind, queryset, since in reads]


def watch_resume(
    *, reads: list[tuple[str, QuerySet]], span: Span, limit: int
) -> tuple[str, list[list[Model]]]:
    """What a stream that stopped at `span` has not had yet, for each (kind, queryset), and the position it
    goes on from: the rest of an interrupted read (`span.until`), else everything up to now.

    FeedPositionInvalid for positions this feed cannot have given out; FeedPositionExpired if the trim has
    deleted changes the stream had not had, or if a kind has more than `limit` of them (a new snapshot is
    then the smaller answer)."""
    positions = [span.since] if span.until is None else [span.since, span.until]
    if not all(_position_valid(position) for position in positions):
        raise FeedPositionInvalid("not a feed position")
    with _at_feed_position() as now:
        with connection.cursor() as cursor:
            cursor.execute(
                f"""
                SELECT pg_snapshot_xmax(%(since)s::pg_snapshot) <= pg_snapshot_xmax(%(until)s::pg_snapshot)
                    AND pg_snapshot_xmin(%(since)s::pg_snapshot) <= pg_snapshot_xmin(%(until)s::pg_snapshot)
                    AND pg_snapshot_xmax(%(until)s::pg_snapshot) <= pg_snapshot_xmax(%(now)s::pg_snapshot),
                    EXISTS (SELECT 1 FROM {TrimMark._meta.db_table}
                            WHERE xid >= pg_snapshot_xmin(%(since)s::pg_snapshot))
                """,
                {"since": span.since, "until": span.until or now, "now": now},
            )
            ordered, trimmed = cursor.fetchone()
        if not ordered:
            raise FeedPositionInvalid("a position this feed has not reached")
        if trimmed:
            raise FeedPositionExpired("the feed has been trimmed past this position")
        changes = [_changed(kind, queryset, span, limit=limit + 1) for kind, queryset in reads]
        if any(len(rows) > limit for rows in changes):
            raise FeedPositionExpired(f"more than {limit} changes since this position")
        return span.until or now, changes


def _position_valid(text: str) -> bool:
    """A pg_snapshot PostgreSQL would read: 0 < xmin <= xip... < xmax, in order."""
    match = POSITION.match(text)
    if match is None:
        return False
    xmin, xmax = int(match[1]), int(match[2])
    xip = [int(xid) for xid in match[3].split(",")] if match[3] else []
    return 0 < xmin <= xmax and all(xmin <= xid < xmax for xid in xip) and xip == sorted(xip)


def _changed(kind: str, queryset: QuerySet, span: Span, *, limit: int | None = None) -> list[Model]:
    """The list endpoint's own query (its filters) runs over the changes' row images, which a CTE named as
    the table stands for."""
    model = queryset.model
    table = connection.ops.quote_name(model._meta.db_table)
    ordered = queryset.order_by().annotate(change_id=RawSQL(f"{table}.change_id", [])).order_by("change_id")
    if limit is not None:
        ordered = ordered[:limit]
    sql, params = ordered.query.sql_with_params()
    until = "" if span.until is None else "AND pg_visible_in_snapshot(c.xid, %s::pg_snapshot)"
    images = f"""
        WITH {table} AS (
            SELECT c.id AS change_id, r.*
            FROM {Change._meta.db_table} c
            CROSS JOIN LATERAL jsonb_populate_record(NULL::{table}, c.image) r
            WHERE c.kind = %s AND c.xid >= pg_snapshot_xmin(%s::pg_snapshot)
                AND NOT pg_visible_in_snapshot(c.xid, %s::pg_snapshot) {until} AND c.id > %s
        )
    """
    window = [kind, span.since, span.since, *([] if span.until is None else [span.until]), span.after]
    return list(model.objects.raw(images + sql, [*window, *params]))
