"""Missions as plain SQL rows, for the hot writes: the API's insert, the step's reads and updates.

As plain SQL they skip the ORM's query compiler, which costs more than the queries themselves.
"""

from collections.abc import Mapping
from dataclasses import fields
from datetime import UTC, datetime
from typing import Any

import orjson
from django.db import connection
from django.db.models import JSONField

from dispatch.records import MissionRecord, ZoneReach
from dispatch.vocabulary import Lifecycle, MissionState, StationKind
from kit.db import json_column, jsonb
from missions.models import Mission
from robots.models import Robot
from stations.models import Station
from vda5050.models import ActionType

MISSION_FIELDS = {field.name: field for field in Mission._meta.concrete_fields}
MISSION_JSON_FIELDS = frozenset(name for name, f in MISSION_FIELDS.items() if isinstance(f, JSONField))


def mission_db_values(values: Mapping[str, Any]) -> list[Any]:
    """Field values (by field name) as the database takes them, JSON adapted, in order."""
    return [
        jsonb(value)
        if name in MISSION_JSON_FIELDS and value is not None
        else MISSION_FIELDS[name].get_db_prep_save(value, connection)
        for name, value in values.items()
    ]


def mission_columns(names: tuple[str, ...]) -> list[str]:
    return [connection.ops.quote_name(MISSION_FIELDS[name].column) for name in names]


# The columns of a step's mission record (`mission_records`), in the record's order.
MISSION_RECORD_FIELDS = tuple(f.name for f in fields(MissionRecord))
# Django leaves JSON columns undecoded for JSONField to decode; a plain read decodes them itself.
MISSION_RECORD_JSON = tuple(isinstance(MISSION_FIELDS[name], JSONField) for name in MISSION_RECORD_FIELDS)


def mission_records(rows: list[tuple[Any, ...]]) -> list[MissionRecord]:
    """Rows of MISSION_RECORD_FIELDS' columns as the engine's records."""
    return [
        MissionRecord(
            *(
                orjson.loads(value) if is_json and value is not None else value
                for value, is_json in zip(row, MISSION_RECORD_JSON, strict=True)
            )
        )
        for row in rows
    ]


# A step may end the robot's last mission without seeing a mission created meanwhile (it read the queue
# before the INSERT committed), while the INSERT saw the ending mission still RUNNING. The robot's queue lock
# (an advisory lock, released when the transaction ends) settles which of the two starts it. The creation
# takes the lock shared before it looks at the queue and holds it to its commit; a step that ended the
# robot's last mission takes it exclusively before its COMMIT, then looks at the queue again
# (QUEUE_GREW_SQL) and steps again if a mission came. So the step waits for a creation in flight and sees
# its mission (the creation, looking before the step's commit, saw the ending mission and did not wake the
# robot), and a creation that waited for the step sees the step's commit and wakes the robot (the step's
# look, before that creation committed, did not see it). Either way one of them starts the mission, never
# both. Creations do not wait for each other, nor for anything a step holds.
ROBOT_QUEUE_LOCK_SPACE = 5050  # the lock's first key; the second is the robot's name hashed
ROBOT_QUEUE_LOCK_SQL = f"SELECT pg_advisory_xact_lock({ROBOT_QUEUE_LOCK_SPACE}, hashtext(%s))"

MISSION_DELETE_SQL = f"DELETE FROM {Mission._meta.db_table} WHERE name = %s"


def mission_row_delete(name: str) -> None:
    with connection.cursor() as cursor:
        cursor.execute(MISSION_DELETE_SQL, [name])


# A live mission that keeps its robot busy: running, or bound by assignment and not started yet. The state
# list lets mission_queue_idx find a robot's live missions alone, not its whole history.
_BUSY_MISSION_SQL = f"""
    busy.state IN ('{MissionState.RUNNING}', '{MissionState.PENDING}')
    AND (busy.state = '{MissionState.RUNNING}' OR busy.assignment <> '[]')
"""
# Every busy robot, as a set: for a read of many robots, `name IN (BUSY_ROBOTS_SQL)` is one scan of the live
# missions hashed once, where robot_busy_sql per robot is an index probe per robot (and, planned while the
# tables are still small, a scan of the robot's whole history or of every live mission per robot).
BUSY_ROBOTS_SQL = f"""
    SELECT busy.robot FROM {Mission._meta.db_table} busy WHERE busy.robot IS NOT NULL AND {_BUSY_MISSION_SQL}
"""


def robot_busy_sql(robot: str) -> str:
    """EXISTS: the robot (an SQL expression) has a running mission, or one assignment bound to it that has
    not started yet."""
    return f"""
        EXISTS (
            SELECT 1 FROM {Mission._meta.db_table} busy WHERE busy.robot = {robot} AND {_BUSY_MISSION_SQL}
        )
    """


def factsheet_actions_sql(robot: str) -> str:
    """The action list of robot `robot`'s (a table alias) factsheet, under its 2.x or its 3.0 key."""
    return f"""COALESCE(
        {robot}.factsheet #> '{{protocolFeatures,agvActions}}',
        {robot}.factsheet #> '{{protocolFeatures,mobileRobotActions}}'
    )"""


def can_charge_sql(robot: str) -> str:
    """Robot `robot`'s factsheet lists `startCharging`: a charging trip may be sent to it."""
    return f"""{factsheet_actions_sql(robot)} @> '[{{"actionType": "{ActionType.START_CHARGING}"}}]'::jsonb"""


def robot_charge_threshold_sql(robot: str) -> str:
    """The battery level at or below which robot `robot` (a table alias) charges before any mission but its
    trip to a charger: its recommended minimum (its critical level where it has none, as
    `dispatch.stations.Battery.low`), where it can charge (`startCharging` in its factsheet) at a charger it
    may use on its map; NULL where it cannot, or while its stored level is above it — then nothing else of
    the robot is read (the step reads this on every step; its factsheet is large)."""
    threshold = f"GREATEST({robot}.battery_critical_level, {robot}.battery_recommended_minimum)"
    return f"""
        CASE WHEN {robot}.battery_level <= {threshold} AND {can_charge_sql(robot)}
            AND EXISTS (
                SELECT 1 FROM {Station._meta.db_table} charger
                WHERE charger.kind = '{StationKind.CHARGER}' AND charger.lifecycle = '{Lifecycle.ALIVE}'
                  AND charger.pose_map_id = {robot}.pose_map_id
                  AND (charger.robot_types = '[]'::jsonb OR charger.robot_types ? {robot}.agv_class)
            )
        THEN {threshold} END
    """


def robots_column_write_sql(column: str, sql_type: str) -> str:
    """Set `column` of many robots at once, each its own value (parameters: the names, the values as a
    `sql_type` array). A robot a step or the bridge's flush holds is skipped, not waited for: a plan run
    writes what its robots show, and the next run writes what this one skipped."""
    return f"""
    WITH given AS (SELECT * FROM unnest(%s::varchar[], %s::{sql_type}[]) AS g(name, value)),
        free AS (
            SELECT name FROM {Robot._meta.db_table} WHERE name IN (SELECT name FROM given)
            FOR NO KEY UPDATE SKIP LOCKED
        )
    UPDATE {Robot._meta.db_table} AS r SET {column} = g.value
    FROM given AS g WHERE r.name = g.name AND r.name IN (SELECT name FROM free)
"""


def zone_reach_record(
    order_id: str | None, release_through: int | None, waiting: Any, responses: Any, *, due: bool = False
) -> ZoneReach:
    """A robot's zone reach row (`zones.models.ZoneReach`, JSON columns as read) as the step and the zone
    plan take it; `due`: answers the robot was not sent yet."""
    return ZoneReach(
        order_id=order_id,
        release_through=release_through,
        waiting=tuple(json_column(waiting) or ()),
        responses=tuple((request, grant) for request, grant in json_column(responses) or ()),
        responses_due=due,
    )


def binding_time(at: datetime) -> str:
    """A time in a mission's assignment record, as the API writes times."""
    return at.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def binding_record(robot: str, at: datetime) -> dict[str, Any]:
    """The entry a binding adds to a mission's assignment history (as `missions.services.BIND_SQL` writes
    it): released_at and reason stay empty until the binding is released (`_release_sql`)."""
    return {"robot": robot, "bound_at": binding_time(at), "released_at": None, "reason": None}


def _release_sql(condition: str) -> str:
    """Unbind the queued missions assignment bound that meet `condition`: robot null again, the latest
    binding released (when, why). Parameters: updated_at, released_at (`binding_time`), reason, then
    the condition's."""
    return f"""
        UPDATE {Mission._meta.db_table} AS m
        SET robot = NULL, updated_at = %s, assignment = jsonb_set(
            m.assignment,
            ARRAY[(jsonb_array_length(m.assignment) - 1)::text],
            (m.assignment -> -1) || jsonb_build_object('released_at', %s::text, 'reason', %s::text)
        )
        WHERE m.robot IS NOT NULL AND m.state = '{MissionState.PENDING}' AND m.assignment <> '[]'
          AND {condition}
        RETURNING m.name
    """


# The step's: the robot it could not start the mission on gives it back. Parameters: ..., mission, robot.
RELEASE_SQL = _release_sql("m.name = %s AND m.robot = %s")
# Assignment's: the robot was deleted (its step, finding no robot, sees none of its missions).
RELEASE_ORPHANS_SQL = _release_sql(
    f"NOT EXISTS (SELECT 1 FROM {Robot._meta.db_table} r WHERE r.name = m.robot)"
)
ROBOT_DELETED = "Robot was deleted"
