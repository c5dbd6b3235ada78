"""Writes of what robots report and whether they are heard: the bridge's status flush and online marks,
and beat's heartbeat check. None of them wakes a step but the heartbeat check's: the engine reads a
robot's live state from Redis, not these columns."""

import time
from collections.abc import Sequence
from functools import cache
from typing import Any

from django.conf import settings
from django.db import connection, transaction

from kit.wake import request_assignment, request_steps
from robots import livestate
from robots.choices import SettingSource
from robots.models import InstantAction, Robot
from robots.services import FACTSHEET_REQUEST, instant_action


def robots_came_online(*, names: Sequence[str]) -> None:
    """Mark robots online, ask each for its factsheet (sent by its next step, which the caller requests)
    unless a request is already waiting, and ask for an assignment run.

    One transaction for them all: robots come online in bursts (a fleet starting, a broker restart), and
    the bridge does this between two batches of messages. The rows are locked first, in name order, so two
    callers cannot deadlock and the check for a waiting request cannot race with another's insert.
    """
    with transaction.atomic():
        locked = list(
            Robot.objects.select_for_update()
            .filter(name__in=names)
            .order_by("name")
            .values_list("name", flat=True)
        )
        Robot.objects.filter(name__in=locked).update(online=True)
        request_assignment()  # robots back online may take unbound missions
        if not settings.DISPATCH_REQUEST_FACTSHEET:
            return
        waiting = set(
            InstantAction.objects.filter(
                robot_id__in=locked, action_type=FACTSHEET_REQUEST, status__isnull=True
            ).values_list("robot_id", flat=True)
        )
        InstantAction.objects.bulk_create(
            [instant_action(name, FACTSHEET_REQUEST) for name in locked if name not in waiting]
        )


def robot_protocol_version_learn(*, name: str, version: str) -> bool:
    """Speak `version` to the robot from now on, as its own messages say, unless an operator chose its
    version; True if that changed it. Its step (which the caller requests) sends what waits anew."""
    return bool(
        Robot.objects.filter(name=name)
        .exclude(protocol_version_source=SettingSource.OPERATOR)
        .exclude(protocol_version=version, protocol_version_source=SettingSource.LEARNED)
        .update(protocol_version=version, protocol_version_source=SettingSource.LEARNED)
    )


def robot_check_heartbeats(*, now: float | None = None) -> list[str]:
    """Make each robot's `online` follow what the bridges heard: offline once silent for longer than its
    heartbeat_timeout, online again once heard within it; returns the robots whose flag changed.

    The second half is what keeps the flag from staying wrong: the bridge marks a robot online in Redis
    and then in PostgreSQL, and a bridge killed or a database away between the two left a robot offline
    for good while it kept publishing.
    """
    now = time.time() if now is None else now
    robots = list(Robot.objects.values_list("name", "heartbeat_timeout", "online"))
    last_seen = livestate.last_seen([name for name, _, _ in robots])
    silent, heard = [], []
    for name, timeout, online in robots:
        recent = last_seen[name] is not None and last_seen[name] + timeout >= now
        if online and not recent:
            silent.append(name)
        elif not online and recent:
            heard.append(name)
    if silent:
        Robot.objects.filter(name__in=silent).update(online=False)
        for name in silent:
            livestate.mark_offline(name)
    if heard:
        robots_came_online(names=heard)
        livestate.mark_online(heard)
    if silent or heard:
        request_steps([*silent, *heard])
    return [*silent, *heard]


ROBOTS_BY_NAME_SQL = f"SELECT name FROM {Robot._meta.db_table} WHERE name = ANY(%s)"


def robot_status_write(*, columns: tuple[str, ...], rows: list[tuple[Any, ...]]) -> set[str]:
    """The bridge's status flush: write `columns` of each row's robot (the values, then the robot's name)
    unless another transaction holds the robot; returns the robots skipped that way. A write that takes a
    robot's battery down to its low mark (its minimum, else its critical level) asks for an assignment run,
    which sends low robots to charge.

    A robot a step holds is skipped, not waited for: waiting, the flush held the rows it had locked, and
    the steps of those robots queued behind the step it waited for (and two bridges' flushes never
    deadlock). One statement locks, writes and (outside a transaction) commits, so the rows are held only
    while it runs: a step that comes for one of them waits for no round trip of the flush. One more read
    when some were skipped. Deleted robots are not skipped.
    """
    names = [row[-1] for row in rows]
    with connection.cursor() as cursor:
        cursor.execute(_status_write_sql(columns), [list(values) for values in zip(*rows, strict=True)])
        results = cursor.fetchall()
        if any(ran_low for _, ran_low in results):
            request_assignment()  # the run that sends robots to charge (missions.trips)
        written = {name for name, _ in results}
        if len(written) == len(names):
            return set()
        cursor.execute(ROBOTS_BY_NAME_SQL, [[name for name in names if name not in written]])
        return {name for (name,) in cursor.fetchall()}


# A robot's battery at or below this is low: it goes to charge (dispatch.stations.Battery.low).
LOW_BATTERY_SQL = "GREATEST(r.battery_critical_level, COALESCE(r.battery_recommended_minimum, 0))"


@cache
def _status_write_sql(columns: tuple[str, ...]) -> str:
    """One array per column (then the names): the same statement whatever the number of robots. It returns
    each robot written, and whether that write took its battery from above its low mark to it or below
    (the old level is the locked row's, read before the update)."""
    fields = [Robot._meta.get_field(column) for column in (*columns, "name")]
    arrays = ", ".join(f"%s::{field.db_type(connection)}[]" for field in fields)
    quoted = [connection.ops.quote_name(field.column) for field in fields]
    assignments = ", ".join(f"{column} = v.{column}" for column in quoted[:-1])
    table = Robot._meta.db_table
    ran_low = (
        f"f.battery_level > {LOW_BATTERY_SQL} AND r.battery_level <= {LOW_BATTERY_SQL}"
        if "battery_level" in columns
        else "false"
    )
    return f"""
        WITH status AS (SELECT * FROM unnest({arrays}) AS v({", ".join(quoted)})),
            free AS (
                SELECT name, battery_level FROM {table} WHERE name IN (SELECT name FROM status)
                FOR NO KEY UPDATE SKIP LOCKED
            )
        UPDATE {table} AS r SET {assignments}
        FROM status AS v, free AS f WHERE r.name = v.name AND r.name = f.name
        RETURNING r.name, {ran_low}
    """
