"""Access to RELEASE zones (issue 46): the zone plan's I/O around the pure `dispatch.zones.decide`.

A run takes the plan's advisory lock (runs take turns, whatever number of workers run one at once or are
killed mid-run), reads the maps' enabled RELEASE zones, every robot with its running mission's order and
progress and its zone reach, the grants, and the robots' positions (the 3.0 ones' zoneRequests too) from
their latest states; decides;
and writes in the same transaction the grants, each robot's reach (how far its order's base may go, which
zones it waits for, the answers to its requests) and the zones each robot holds and waits for in its status.
The robots whose reach changed, and those whose order's base is still behind their reach, get a step, which
carries it out (`dispatch.step._reach_further`, the responses topic): beat's runs make up for a step that
missed a reach.

A robot counts while it is online (heard within its heartbeat timeout), alive and reporting a position: one
offline, being deleted or deleted holds nothing. The route a robot still drives is the nodes of its running
mission's order past the last one it reached; the order's base is what it has released. With no enabled
RELEASE zone, the run removes every grant and reach (the steps then release what orders held back).
"""

from collections.abc import Iterable
from dataclasses import dataclass, replace
from datetime import datetime
from typing import Any

import orjson
from django.db import connection, transaction
from django.db.backends.utils import CursorWrapper
from django.utils import timezone

from dispatch.records import ZoneReach
from dispatch.vocabulary import Lifecycle, MissionState
from dispatch.zones import RobotRoute, RoutePoint, Zone, ZoneDecision, ZoneKey, decide, zone_requests
from kit.db import json_column, jsonb
from kit.wake import request_steps
from missions.models import Mission
from missions.rows import robots_column_write_sql, zone_reach_record
from robots import livestate
from robots.models import Robot
from vda5050.codec import parse_state
from vda5050.errors import ProtocolError
from vda5050.versions import V3_0
from vda5050.zones import GrantType, ZoneType
from zones.models import ZoneGrant, ZoneSet
from zones.models import ZoneReach as ZoneReachRow

ZONES_LOCK_SPACE = 5051  # the advisory lock serialising runs (missions.rows uses 5050 for robots' queues)
LOCK_SQL = f"SELECT pg_advisory_xact_lock({ZONES_LOCK_SPACE}, 0)"
ENABLED_SQL = f"SELECT map_id, name, zones FROM {ZoneSet._meta.db_table} WHERE enabled"
_REACH = ZoneReachRow._meta.db_table
_GRANTS = ZoneGrant._meta.db_table
_ROBOTS = Robot._meta.db_table
# Every robot: whether it counts, its position, version, shown zone access; its running mission's priority,
# age, order and progress; its reach as stored.
ROBOTS_SQL = f"""
    SELECT r.name, r.online AND r.lifecycle = '{Lifecycle.ALIVE}' AND r.last_state_at IS NOT NULL,
        r.pose_x, r.pose_y, r.pose_map_id, r.protocol_version, r.zone_access,
        m.priority, m.created_at, m."order", m.progress,
        z.robot IS NOT NULL, z.order_id, z.release_through, z.waiting, z.responses, z.responses_version
    FROM {_ROBOTS} r
    LEFT JOIN LATERAL (
        SELECT priority, created_at, "order", progress FROM {Mission._meta.db_table} m
        WHERE m.robot = r.name AND m.state = '{MissionState.RUNNING}' LIMIT 1
    ) AS m ON true
    LEFT JOIN {_REACH} z ON z.robot = r.name
"""
GRANTS_SQL = (
    f"SELECT id, map_id, zone_id, robot, revoked_at IS NOT NULL FROM {_GRANTS} ORDER BY granted_at, id"
)
GRANTS_DELETE_SQL = f"DELETE FROM {_GRANTS} WHERE id = ANY(%s)"
GRANTS_INSERT_SQL = f"""
    INSERT INTO {_GRANTS} (map_id, zone_id, robot, granted_at)
    SELECT *, %s FROM unnest(%s::text[], %s::text[], %s::varchar[])
"""
REACH_UPSERT_SQL = f"""
    INSERT INTO {_REACH} (robot, order_id, release_through, waiting, responses, responses_version,
        responses_sent, updated_at)
    SELECT name, order_id, through, waiting, responses, version, 0, %s
    FROM unnest(%s::varchar[], %s::text[], %s::integer[], %s::jsonb[], %s::jsonb[], %s::integer[])
        AS v(name, order_id, through, waiting, responses, version)
    ON CONFLICT (robot) DO UPDATE SET order_id = EXCLUDED.order_id,
        release_through = EXCLUDED.release_through,
        waiting = EXCLUDED.waiting, responses = EXCLUDED.responses,
        responses_version = EXCLUDED.responses_version, updated_at = EXCLUDED.updated_at
"""
REACH_DELETE_SQL = f"DELETE FROM {_REACH} WHERE robot = ANY(%s)"
# Deleted robots hold nothing: their grants are let go by the decision (they are not among the robots).
REACH_ORPHANS_DELETE_SQL = (
    f"DELETE FROM {_REACH} z WHERE NOT EXISTS (SELECT 1 FROM {_ROBOTS} r WHERE r.name = z.robot)"
)
ZONE_ACCESS_SQL = robots_column_write_sql("zone_access", "jsonb")


@dataclass
class _Robot:
    name: str
    counts: bool
    route: RobotRoute
    sequence_ids: tuple[int, ...]  # of the route's nodes
    reached: int  # the sequenceId of the order's node the robot last reached
    order_id: str | None
    is_3: bool
    zone_access: Any
    stored: ZoneReach | None
    responses_version: int


def zones_plan_run() -> ZoneDecision | None:
    """Decide who holds which RELEASE zone and how far each order may reach, store it and step the robots
    it changes; None if no map has an enabled RELEASE zone (everything zones held is let go)."""
    now = timezone.now()
    with transaction.atomic(), connection.cursor() as cursor:
        cursor.execute(LOCK_SQL)
        cursor.execute(ENABLED_SQL)
        enabled: dict[str, str] = {}
        zones: list[Zone] = []
        for map_id, zone_set, content in cursor.fetchall():
            enabled[map_id] = zone_set
            zones += _release_zones(map_id, json_column(content))
        cursor.execute(ROBOTS_SQL)
        robots = [_robot(*row) for row in cursor.fetchall()]
        if not zones:
            _let_go(cursor, robots)
            return None
        cursor.execute(GRANTS_SQL)
        grants = cursor.fetchall()
        rejected = _with_latest_states(robots, enabled)
        holders: dict[ZoneKey, list[str]] = {}
        for _, map_id, zone_id, robot, _ in grants:
            holders.setdefault((map_id, zone_id), []).append(robot)
        decision = decide(
            zones=zones,
            robots=[robot.route for robot in robots if robot.counts],
            holders=holders,
            revoked=[(robot, (map_id, zone_id)) for _, map_id, zone_id, robot, revoked in grants if revoked],
        )
        cursor.execute(REACH_ORPHANS_DELETE_SQL)
        _grants_write(cursor, grants, decision, now)
        changed = _reaches_write(cursor, robots, decision, rejected, now)
        _zone_access_write(cursor, robots, decision)
        to_step = list(dict.fromkeys([*changed, *_behind(robots, decision)]))
        if to_step:
            request_steps(to_step)
    return decision


def _release_zones(map_id: str, zones: Iterable[dict[str, Any]]) -> list[Zone]:
    return [
        Zone(
            map_id=map_id,
            zone_id=zone["zone_id"],
            vertices=tuple((float(v["x"]), float(v["y"])) for v in zone["vertices"]),
            capacity=int(zone.get("capacity") or 1),
        )
        for zone in zones
        if zone["zone_type"] == ZoneType.RELEASE
    ]


def _robot(
    name: str,
    counts: bool,
    x: float,
    y: float,
    map_id: str,
    version: str,
    zone_access: Any,
    priority: int | None,
    created_at: datetime | None,
    order: Any,
    progress: Any,
    has_reach: bool,
    reach_order_id: str | None,
    release_through: int | None,
    waiting: Any,
    responses: Any,
    responses_version: int | None,
) -> _Robot:
    """A robot as the run sees it: its route ahead on its running mission's order (nodes past the last one
    it reached, as far as its progress shows; its base: those released)."""
    order, progress = json_column(order), json_column(progress)
    nodes: list[dict[str, Any]] = []
    reached = 0
    if order is not None:
        if progress is not None and progress.get("orderId") == order["orderId"]:
            reached = progress["lastNodeSequenceId"]
        nodes = [node for node in order["nodes"] if node["sequenceId"] > reached and node.get("nodePosition")]
    route = RobotRoute(
        robot=name,
        priority=priority or 0,
        since=created_at.timestamp() if created_at is not None else 0.0,
        position=RoutePoint(x, y, map_id),
        route=tuple(
            RoutePoint(node["nodePosition"]["x"], node["nodePosition"]["y"], node["nodePosition"]["mapId"])
            for node in nodes
        ),
        released=sum(1 for node in nodes if node["released"]),
    )
    stored = None
    if has_reach:
        stored = zone_reach_record(reach_order_id, release_through, waiting, responses)
    return _Robot(
        name=name,
        counts=counts,
        route=route,
        sequence_ids=tuple(node["sequenceId"] for node in nodes),
        reached=reached,
        order_id=order["orderId"] if order is not None else None,
        is_3=version == V3_0,
        zone_access=json_column(zone_access),
        stored=stored,
        responses_version=responses_version or 0,
    )


def _with_latest_states(robots: list[_Robot], enabled: dict[str, str]) -> dict[str, tuple[str, ...]]:
    """Give the robots that count their position from their latest states, and the 3.0 ones their
    zoneRequests; the requests to answer REJECTED at once, per robot (`dispatch.zones.zone_requests`). One
    round trip to Redis.

    The position is the latest state's, not the robot row's: the row's (the bridge's status flush) may
    be older than the progress the step wrote from a later state, and a robot placed back on its route's
    previous edge could seem to touch no zone where it drives now. The latest state is at least as new as
    the progress."""
    counting = [robot for robot in robots if robot.counts]
    payloads = livestate.states([robot.name for robot in counting])
    rejected: dict[str, tuple[str, ...]] = {}
    for robot in counting:
        payload = payloads[robot.name]
        if payload is None:
            continue
        if not robot.is_3:  # 2.x: its position alone, without a full parse
            position = orjson.loads(payload).get("agvPosition")
            if isinstance(position, dict):
                where = RoutePoint(float(position["x"]), float(position["y"]), str(position["mapId"]))
                robot.route = replace(robot.route, position=where)
            continue
        try:
            state = parse_state(payload)  # 3.0 names its position mobileRobotPosition on the wire
        except ProtocolError:
            continue  # the bridge only stores states it could parse
        if state.agv_position is not None:
            where = RoutePoint(state.agv_position.x, state.agv_position.y, state.agv_position.map_id)
            robot.route = replace(robot.route, position=where)
        taken, rejected[robot.name] = zone_requests(state.zone_requests or [], enabled)
        robot.route = replace(robot.route, requests=taken)
    return rejected


def _grants_write(
    cursor: CursorWrapper, grants: list[tuple[Any, ...]], decision: ZoneDecision, now: datetime
) -> None:
    """The grants as decided: those let go deleted, the new ones inserted. A grant that stands keeps its
    granted_at, and its revocation: a robot revoked inside the zone holds it until it has left, answered
    REVOKED at every run meanwhile (`dispatch.zones.decide`), not granted again by the run after."""
    wanted = {(key, robot) for key, names in decision.holders.items() for robot in names}
    standing = {((map_id, zone_id), robot) for _, map_id, zone_id, robot, _ in grants}
    gone = [
        grant_id for grant_id, map_id, zone_id, robot, _ in grants if ((map_id, zone_id), robot) not in wanted
    ]
    if gone:
        cursor.execute(GRANTS_DELETE_SQL, [gone])
    new = [grant for grant in wanted if grant not in standing]
    if new:
        new.sort()
        cursor.execute(
            GRANTS_INSERT_SQL,
            [now, [key[0] for key, _ in new], [key[1] for key, _ in new], [robot for _, robot in new]],
        )


def _reaches_write(
    cursor: CursorWrapper,
    robots: list[_Robot],
    decision: ZoneDecision,
    rejected: dict[str, tuple[str, ...]],
    now: datetime,
) -> list[str]:
    """Each robot's reach as decided, written where it changed; the robots whose reach changed."""
    changed: list[tuple[_Robot, ZoneReach, int]] = []
    for robot in robots:
        reach = _reach_of(robot, decision, rejected.get(robot.name, ()))
        if reach == robot.stored:
            continue
        version = robot.responses_version
        if reach.responses != (robot.stored.responses if robot.stored else ()):
            version += 1
        changed.append((robot, reach, version))
    if changed:
        cursor.execute(
            REACH_UPSERT_SQL,
            [
                now,
                [robot.name for robot, _, _ in changed],
                [reach.order_id for _, reach, _ in changed],
                [reach.release_through for _, reach, _ in changed],
                [jsonb(list(reach.waiting)) for _, reach, _ in changed],
                [jsonb([list(answer) for answer in reach.responses]) for _, reach, _ in changed],
                [version for _, _, version in changed],
            ],
        )
    return [robot.name for robot, _, _ in changed]


def _behind(robots: list[_Robot], decision: ZoneDecision) -> list[str]:
    """The robots whose order's base holds fewer nodes than the plan allows: their step has not extended it
    yet. Asked for again at every run, not only when the reach changes: a step may have missed the change
    (it read the robot just before this run committed, and its queued-step marker deduplicated this run's
    request), or could not extend then (its order not yet accepted, a cancel pending)."""
    return [
        robot.name
        for robot in robots
        if robot.counts and decision.horizons.get(robot.name, 0) > robot.route.released
    ]


def _reach_of(robot: _Robot, decision: ZoneDecision, rejected: tuple[str, ...]) -> ZoneReach:
    """How far the robot's order may reach: through its route's `horizon` nodes (never less than its base
    holds: `decide` sees to that); a robot that does not count, no further than its base."""
    horizon = decision.horizons.get(robot.name) if robot.counts else None
    through = None
    if robot.order_id is not None and horizon is not None:
        through = robot.sequence_ids[horizon - 1] if horizon else robot.reached
    waiting = tuple(sorted(zone_id for _, zone_id in decision.waiting.get(robot.name, ())))
    answers = decision.responses.get(robot.name, ())
    responses = (*answers, *((request, GrantType.REJECTED.value) for request in rejected))
    return ZoneReach(
        order_id=robot.order_id if through is not None else None,
        release_through=through,
        waiting=waiting,
        responses=tuple((request, str(grant)) for request, grant in responses),
    )


def _zone_access_write(cursor: CursorWrapper, robots: list[_Robot], decision: ZoneDecision) -> None:
    """The zones each robot holds and waits for, in its status, where that changed."""
    held: dict[str, list[ZoneKey]] = {}
    for key, names in decision.holders.items():
        for name in names:
            held.setdefault(name, []).append(key)
    access = {
        robot.name: {
            "held": _zone_list(held.get(robot.name, ())),
            "waiting": _zone_list(decision.waiting.get(robot.name, ())),
        }
        for robot in robots
    }
    _zone_access_update(cursor, robots, access)


def _zone_list(keys: Iterable[ZoneKey]) -> list[dict[str, str]]:
    return [{"map_id": map_id, "zone_id": zone_id} for map_id, zone_id in sorted(keys)]


def _zone_access_update(cursor: CursorWrapper, robots: list[_Robot], access: dict[str, Any]) -> None:
    changed = {robot.name: access[robot.name] for robot in robots if robot.zone_access != access[robot.name]}
    if changed:
        cursor.execute(ZONE_ACCESS_SQL, [list(changed), [jsonb(value) for value in changed.values()]])


def _let_go(cursor: CursorWrapper, robots: list[_Robot]) -> None:
    """No enabled RELEASE zone: no grants, no reaches (their robots' steps release what orders held back),
    nothing held or waited for in the robots' status. The robots whose order is still held back are
    stepped at every run (beat runs it while one is, `missions.selectors.orders_held_back`), as `_behind`."""
    cursor.execute(f"DELETE FROM {_GRANTS}")
    reached = [robot.name for robot in robots if robot.stored is not None]
    if reached:
        cursor.execute(REACH_DELETE_SQL, [reached])
    held_back = [
        robot.name for robot in robots if robot.counts and robot.route.released < len(robot.route.route)
    ]
    to_step = list(dict.fromkeys([*reached, *held_back]))
    if to_step:
        request_steps(to_step)
    _zone_access_update(cursor, robots, {robot.name: {} for robot in robots})
