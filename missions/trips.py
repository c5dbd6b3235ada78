"""Charging and parking trips (issue 44): the station plan's I/O around the pure `dispatch.stations`.

A trip is a mission the dispatch core makes itself (`Mission.purpose` CHARGE or PARK), queued ahead of every
client's mission of its robot: a route to the station's pose and, for a charger, the node action
`startCharging` there. So orders, resends, timeouts and failures are the step's, as for any mission.

A run locks every station's row (in name order), reads the robots and their trips with a snapshot taken
after the locks, plans, and writes in the same transaction the stations' reservations, the new trips,
the trips canceled and the stopCharging actions. Runs wait for each other on those locks, so whatever
number of workers run at once (or are killed mid-run), a station never holds more than its capacity.
"""

from collections.abc import Iterable
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.db import connection, transaction
from django.db.backends.utils import CursorWrapper
from django.utils import timezone

from dispatch.assignment import Pose
from dispatch.stations import CHARGED, Battery, StationPlan, StationRobot, StationSite, Trip, plan_stations
from dispatch.vocabulary import Lifecycle, MissionPurpose, MissionState, RobotState, StationKind
from kit.db import json_column, jsonb
from kit.wake import request_steps
from missions.models import Mission
from missions.rows import can_charge_sql, robots_column_write_sql
from missions.services import PRIORITY_MAX, mission_cancel, mission_create
from missions.tuning import TRIP_RETRY_MAX_SECONDS, TRIP_RETRY_SECONDS
from robots.models import InstantAction, Robot
from robots.services import instant_action
from stations.models import Station
from vda5050.models import ActionStatus, ActionType
from vda5050.orders import DEFAULT_ALLOWED_DEVIATION_THETA, DEFAULT_ALLOWED_DEVIATION_XY

# Who the write records of trips name.
TRIP_ACTOR = "dispatch"
# A trip goes ahead of its robot's queue (a running mission is never preempted): the highest priority the API
# allows, so that it stays within what the API documents (only a client's missions of that priority queued
# before it go first; a robot is sent only while idle, when its queue has nothing it can start).
TRIP_PRIORITY = PRIORITY_MAX
PURPOSES = {StationKind.CHARGER: MissionPurpose.CHARGE, StationKind.PARKING: MissionPurpose.PARK}
_UNFINISHED = f"('{MissionState.PENDING}', '{MissionState.RUNNING}')"
_ENDED_UNDONE = f"('{MissionState.FAILED}', '{MissionState.CANCELED}')"

LOCK_STATIONS_SQL = f"""
    SELECT name, kind, pose_x, pose_y, pose_theta, pose_map_id, robot_types, capacity, reservations
    FROM {Station._meta.db_table} ORDER BY name FOR UPDATE
"""
_MISSIONS = Mission._meta.db_table
# Every robot with what the plan needs: idle (no running mission but a parking trip, not in teleop), its
# latest charging trip's state, its failed charging trips since its last charged one (the backoff), since
# when it idles (its last mission's end, else its creation; none while it has a queue), and whether a
# client's mission started since its latest parking trip ended (it left, however short the mission), and
# whether its latest stopCharging since its latest charging trip is not reported FINISHED (pending: not
# taken back at a charger, not told twice; refused: it charges on by itself; one before that trip belongs
# to an earlier charge, and a robot that once refused to stop would never be taken back again).
STATION_ROBOTS_SQL = f"""
    SELECT r.name, r.agv_class, r.last_state_at IS NOT NULL, r.pose_x, r.pose_y, r.pose_map_id,
        r.online AND r.lifecycle = '{Lifecycle.ALIVE}',
        r.state <> '{RobotState.TELEOP}' AND NOT r.switch_teleop AND NOT EXISTS (
            SELECT 1 FROM {_MISSIONS} m WHERE m.robot = r.name AND m.state = '{MissionState.RUNNING}'
              AND m.purpose IS DISTINCT FROM '{MissionPurpose.PARK}'
        ),
        r.battery_level, r.battery_critical_level, r.battery_recommended_minimum,
        r.battery_recommended_maximum, r.state = '{RobotState.CHARGING}',
        {can_charge_sql("r")},
        trip.state, failed.count, failed.last_end,
        CASE WHEN NOT EXISTS (
            SELECT 1 FROM {_MISSIONS} m WHERE m.robot = r.name AND m.state IN {_UNFINISHED}
        ) THEN COALESCE(
            (SELECT max(m.end_timestamp) FROM {_MISSIONS} m WHERE m.robot = r.name), r.created_at
        ) END,
        EXISTS (
            SELECT 1 FROM {_MISSIONS} c WHERE c.robot = r.name AND c.purpose IS NULL
              AND c.start_timestamp > park.end_timestamp
        ),
        r.charge_requested,
        COALESCE((
            SELECT a.status IS DISTINCT FROM '{ActionStatus.FINISHED}' FROM {InstantAction._meta.db_table} a
            WHERE a.robot_id = r.name AND a.action_type = '{ActionType.STOP_CHARGING}'
              AND (trip.created_at IS NULL OR a.created_at >= trip.created_at)
            ORDER BY a.created_at DESC LIMIT 1
        ), false),
        r.charging_waiting_reason
    FROM {Robot._meta.db_table} r
    LEFT JOIN LATERAL (
        SELECT m.state, m.queue_position, m.created_at FROM {_MISSIONS} m
        WHERE m.robot = r.name AND m.purpose = '{MissionPurpose.CHARGE}'
        ORDER BY m.queue_position DESC LIMIT 1
    ) AS trip ON true
    LEFT JOIN LATERAL (
        SELECT count(*) AS count, max(m.end_timestamp) AS last_end FROM {_MISSIONS} m
        WHERE m.robot = r.name AND m.purpose = '{MissionPurpose.CHARGE}' AND m.state IN {_ENDED_UNDONE}
          AND m.queue_position > COALESCE((
            SELECT max(c.queue_position) FROM {_MISSIONS} c
            WHERE c.robot = r.name AND c.purpose = '{MissionPurpose.CHARGE}'
              AND c.state = '{MissionState.COMPLETED}'
          ), 0)
    ) AS failed ON true
    LEFT JOIN LATERAL (
        SELECT m.end_timestamp FROM {_MISSIONS} m
        WHERE m.robot = r.name AND m.purpose = '{MissionPurpose.PARK}'
        ORDER BY m.queue_position DESC LIMIT 1
    ) AS park ON true
"""
# An operator's request ends once the robot holds a charger.
_ROBOTS = Robot._meta.db_table
CHARGING_WAITING_REASONS_SQL = robots_column_write_sql("charging_waiting_reason", "text")
CHARGE_REQUESTS_END_SQL = f"""
    UPDATE {_ROBOTS} SET charge_requested = false
    WHERE name IN (
        SELECT name FROM {_ROBOTS} WHERE name = ANY(%s) AND charge_requested FOR NO KEY UPDATE SKIP LOCKED
    )
"""
RESERVATIONS_SQL = f"""
    UPDATE {Station._meta.db_table} AS s SET reservations = v.reservations, updated_at = %s
    FROM unnest(%s::varchar[], %s::jsonb[]) AS v(name, reservations) WHERE s.name = v.name
"""


def stations_plan_run() -> StationPlan | None:
    """Plan the stations (`dispatch.stations.plan_stations`) and carry the plan out, robots' charging
    waiting reasons included; None if there are no stations."""
    now = timezone.now()
    with transaction.atomic(), connection.cursor() as cursor:
        cursor.execute(LOCK_STATIONS_SQL)
        stations = {row[0]: _station_site(*row) for row in cursor.fetchall()}
        if not stations:
            return None
        cursor.execute(STATION_ROBOTS_SQL)
        rows = cursor.fetchall()
        robots = [_station_robot(*row[:-1]) for row in rows]
        plan = plan_stations(
            robots, list(stations.values()), now=now, park_after_seconds=settings.DISPATCH_PARK_AFTER_SECONDS
        )
        changed = {
            name: list(held)
            for name, held in plan.reservations.items()
            if held != stations[name].reservations
        }
        if changed:
            cursor.execute(RESERVATIONS_SQL, [now, list(changed), [jsonb(v) for v in changed.values()]])
        _trips_cancel(
            (release.robot, PURPOSES[stations[release.station].kind])
            for release in plan.releases
            if release.reason != CHARGED
        )
        for trip in (*plan.charging_trips, *plan.parking_trips):
            _trip_create(trip, stations[trip.station])
        if plan.stop_charging:
            InstantAction.objects.bulk_create(
                [instant_action(name, ActionType.STOP_CHARGING) for name in plan.stop_charging]
            )
            request_steps(plan.stop_charging)
        _robots_write(
            cursor, plan, robots, stored_reasons={row[0]: row[-1] for row in rows}, stations=stations
        )
    return plan


def _robots_write(
    cursor: CursorWrapper,
    plan: StationPlan,
    robots: list[StationRobot],
    *,
    stored_reasons: dict[str, str | None],
    stations: dict[str, StationSite],
) -> None:
    """The robots' charging waiting reasons that changed, and the end of operators' requests to charge
    once the robot holds a charger."""
    reasons = {
        name: plan.waiting.get(name)
        for name, stored in stored_reasons.items()
        if plan.waiting.get(name) != stored
    }
    if reasons:
        cursor.execute(CHARGING_WAITING_REASONS_SQL, [list(reasons), list(reasons.values())])
    holders = {
        name
        for station, names in plan.reservations.items()
        if stations[station].kind == StationKind.CHARGER
        for name in names
    }
    asked = [robot.name for robot in robots if robot.charge_now and robot.name in holders]
    if asked:
        cursor.execute(CHARGE_REQUESTS_END_SQL, [asked])


def _trip_create(trip: Trip, station: StationSite) -> None:
    """The trip's mission: a route to the station's pose, then `startCharging` there for a charger."""
    tree: list[dict[str, Any]] = [
        {
            "name": station.name,
            "parent": "root",
            "route": {"waypoints": [_waypoint(station)]},
        }
    ]
    if trip.kind == StationKind.CHARGER:
        tree.append(
            {
                "name": ActionType.START_CHARGING.value,
                "parent": "root",
                "action": {"action_type": ActionType.START_CHARGING.value, "action_parameters": {}},
            }
        )
    purpose = PURPOSES[trip.kind]
    mission_create(
        actor=TRIP_ACTOR,
        name=None,
        prefix=purpose.lower(),
        spec={"robot": trip.robot, "priority": TRIP_PRIORITY, "purpose": purpose, "mission_tree": tree},
    )


def _waypoint(station: StationSite) -> dict[str, Any]:
    """The station's pose as a stored route waypoint (the API's defaults filled in, as for a client's)."""
    return {
        "x": station.pose.x,
        "y": station.pose.y,
        "theta": station.theta,
        "map_id": station.pose.map_id,
        "allowedDeviationXY": DEFAULT_ALLOWED_DEVIATION_XY,
        "allowedDeviationTheta": DEFAULT_ALLOWED_DEVIATION_THETA,
    }


def _trips_cancel(robot_purposes: Iterable[tuple[str, MissionPurpose]]) -> None:
    """Cancel the unfinished trips of these robots for these purposes (their station was released)."""
    for robot, purpose in robot_purposes:
        for mission in Mission.objects.filter(
            robot=robot, purpose=purpose, state__in=[MissionState.PENDING, MissionState.RUNNING]
        ).exclude(needs_canceled=True):
            mission_cancel(actor=TRIP_ACTOR, mission=mission)


def _station_site(
    name: str,
    kind: str,
    x: float,
    y: float,
    theta: float,
    map_id: str,
    robot_types: Any,
    capacity: int,
    reservations: Any,
) -> StationSite:
    return StationSite(
        name=name,
        kind=StationKind(kind),
        pose=Pose(x, y, map_id),
        robot_types=frozenset(json_column(robot_types) or ()),
        capacity=capacity,
        reservations=tuple(json_column(reservations) or ()),
        theta=theta,
    )


def _station_robot(
    name: str,
    robot_type: str,
    has_pose: bool,
    x: float,
    y: float,
    map_id: str,
    online: bool,
    idle: bool,
    level: float,
    critical_level: float,
    recommended_minimum: float | None,
    recommended_maximum: float | None,
    charging: bool,
    can_charge: bool | None,
    trip_state: str | None,
    failures: int,
    last_failure: datetime | None,
    idle_since: datetime | None,
    left_parking: bool,
    charge_requested: bool,
    stopping: bool,
) -> StationRobot:
    retry_at = None
    if failures and last_failure is not None:
        backoff = min(TRIP_RETRY_SECONDS * 2 ** (failures - 1), TRIP_RETRY_MAX_SECONDS)
        retry_at = last_failure + timedelta(seconds=backoff)
    return StationRobot(
        name=name,
        robot_type=robot_type,
        pose=Pose(x, y, map_id) if has_pose else None,
        online=online,
        idle=idle,
        battery=Battery(level, critical_level, recommended_minimum, recommended_maximum, charging),
        can_charge=bool(can_charge),
        at_station=trip_state == MissionState.COMPLETED,
        idle_since=idle_since,
        trip_failed=trip_state in (MissionState.FAILED, MissionState.CANCELED),
        retry_at=retry_at,
        charge_now=charge_requested,
        left_parking=left_parking,
        stopping=stopping,
    )
