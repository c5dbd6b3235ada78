"""Reads of missions."""

from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, replace
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.db import connection
from django.db.models import DateTimeField, ExpressionWrapper, F, Q, QuerySet, Value
from django.db.models.fields.json import KT
from django.utils import timezone

from dispatch import engine
from dispatch.assignment import CandidateRobot, Pose, QueueHead, RobotSelector, UnboundMission
from dispatch.held import order_finished, order_lacked
from dispatch.vocabulary import (
    DEFAULT_NOTIFY_TIMEOUT,
    Lifecycle,
    MissionState,
    NodeKind,
    RobotState,
)
from kit.api.errors import QueryValidationError
from kit.api.rows import object_get
from kit.db import json_column
from missions.filters import MissionFilter
from missions.models import Mission
from missions.rows import BUSY_ROBOTS_SQL, factsheet_actions_sql, robot_charge_threshold_sql
from missions.tuning import STALLED_MISSION_SECONDS, UNNOTICED_MISSION_SECONDS
from robots import livestate
from robots.models import InstantAction, Robot
from vda5050 import maps
from vda5050.models import MapStatus
from vda5050.state import MODES_WITHOUT_ORDERS
from vda5050.versions import V3_0
from zones.models import ZoneSet


def mission_get(*, name: str, to_change: bool = False) -> Mission:
    """The mission called `name`; a missing one is the reference's 400 (worded for DELETE if `to_change`)."""
    return object_get(Mission.objects.all(), alias="mission", name=name, to_change=to_change)


def mission_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[Mission]:
    """Missions in queue order, narrowed by the GET /mission query filters (MissionFilter); any lifecycle."""
    filterset = MissionFilter(data=filters or {}, queryset=Mission.objects.order_by("queue_position"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def notify_params(*, mission: str, node: str) -> dict[str, Any] | None:
    """The notify node's params if that node is running right now, else None."""
    row = (
        Mission.objects.filter(name=mission, state=MissionState.RUNNING)
        .values("mission_tree", "node_status")
        .first()
    )
    if row is None or row["node_status"].get(node, {}).get("state") != MissionState.RUNNING:
        return None
    for entry in row["mission_tree"]:
        if entry.get("name") == node and "notify" in entry:
            return {"timeout": DEFAULT_NOTIFY_TIMEOUT, **entry["notify"]}
    return None


def orders_held_back() -> bool:
    """A running mission's order announces nodes it has not released: a zone held them back (the only
    horizon the dispatcher sends, `missions.zone_plan`)."""
    return Mission.objects.filter(
        state=MissionState.RUNNING, order__contains={"nodes": [{"released": False}]}
    ).exists()


def robots_due_for_step(*, now: datetime | None = None) -> list[str]:
    """Robots with something that waits on time: a timeout, a deadline, an unacknowledged message, zone
    sets to distribute."""
    now = now or timezone.now()
    order_resend = now - timedelta(seconds=settings.DISPATCH_ORDER_RESEND_SECONDS)
    action_resend = now - timedelta(seconds=settings.DISPATCH_INSTANT_ACTION_RESEND_SECONDS)
    timeout_at = ExpressionWrapper(
        F("start_timestamp") + Value(timedelta(seconds=1)) * F("timeout"), output_field=DateTimeField()
    )
    running = Mission.objects.filter(state=MissionState.RUNNING)
    ending = running.annotate(timeout_at=timeout_at).filter(
        Q(timeout_at__lte=now) | Q(deadline__lte=now) | Q(needs_canceled=True)
    )
    unaccepted = running.filter(order_accepted=False, order_sent_at__lte=order_resend)
    pending = Mission.objects.filter(state=MissionState.PENDING, deadline__lte=now, robot__isnull=False)
    # Queued missions no step has looked at, on robots that run nothing: a creation whose wake-up was lost
    # (Redis away, or the API killed between its commit and the wake-up).
    unnoticed = Mission.objects.filter(
        state=MissionState.PENDING,
        waiting_reason__isnull=True,
        created_at__lte=now - timedelta(seconds=UNNOTICED_MISSION_SECONDS),
        robot__in=Robot.objects.values("name"),
    ).exclude(robot__in=Mission.objects.filter(state=MissionState.RUNNING).values("robot"))
    actions = InstantAction.objects.filter(status__isnull=True).filter(
        Q(sent_at__isnull=True) | Q(sent_at__lte=action_resend)
    )
    names = set(ending.values_list("robot", flat=True))
    names.update(_orders_not_taken(unaccepted))
    names.update(pending.values_list("robot", flat=True))
    names.update(unnoticed.values_list("robot", flat=True))
    names.update(actions.values_list("robot_id", flat=True))
    with connection.cursor() as cursor:
        cursor.execute(ZONE_SETS_DUE_SQL, [action_resend])
        names.update(name for (name,) in cursor.fetchall())
    return sorted(names)


# Online robots that take zone sets, whose reported zone sets are not yet the fleet's (one of their maps'
# enabled sets not ENABLED, or a set held that the fleet has not enabled), and whose last zone set move
# (`dispatch.zone_sets`) is older than the instant actions' resend period, or was never made.
ZONE_SETS_DUE_SQL = f"""
    SELECT r.name FROM {Robot._meta.db_table} r
    WHERE r.online AND r.protocol_version = '{V3_0}' AND r.supported_zones <> '[]'::jsonb
      AND (r.zone_set_moved_at IS NULL OR r.zone_set_moved_at <= %s)
      AND (
        EXISTS (
            SELECT 1 FROM {ZoneSet._meta.db_table} z
            WHERE z.enabled
              AND (z.map_id = r.pose_map_id
                   OR r.maps @> jsonb_build_array(jsonb_build_object('map_id', z.map_id)))
              AND NOT r.zone_sets @> jsonb_build_array(
                  jsonb_build_object('zone_set_id', z.name, 'zone_set_status', '{MapStatus.ENABLED}'))
        )
        OR EXISTS (
            SELECT 1 FROM jsonb_array_elements(r.zone_sets) held
            WHERE NOT EXISTS (
                SELECT 1 FROM {ZoneSet._meta.db_table} z WHERE z.enabled AND z.name = held->>'zone_set_id'
            )
        )
      )
"""


def robots_stalled(*, now: datetime | None = None) -> list[str]:
    """Robots idle at the end of the order their running mission sent, or no longer holding it
    (`order_lacked`: a restarted robot), the mission not moved on since; and robots whose order may have
    stalled (`_orders_maybe_stalled`).

    The last line of defence: the state that ended or lost the order asked for a step, and a step that
    failed is retried; but a process killed with that retry pending, a lost request, or a state too early to
    say (`dispatch.held.arrived_after_order`) leaves nothing else to step the robot, which sends no news
    while it idles.
    """
    now = now or timezone.now()
    rows = list(
        Mission.objects.filter(
            state=MissionState.RUNNING,
            order__isnull=False,
            updated_at__lte=now - timedelta(seconds=STALLED_MISSION_SECONDS),
        ).values_list("robot", "order_sent_at", KT("order__orderId"), KT("order__orderUpdateId"))
    )
    held = livestate.orders_held([robot for robot, *_ in rows])
    ended = {
        robot
        for robot, sent_at, order_id, update_id in rows
        if update_id is not None
        and sent_at is not None
        and (
            order_finished(held[robot], order_id=order_id, update_id=int(update_id))
            or order_lacked(held[robot], order_id=order_id, update_id=int(update_id), sent_at=sent_at)
        )
    }
    return sorted(ended | set(_orders_maybe_stalled(now)))


def _orders_maybe_stalled(now: datetime) -> list[str]:
    """Robots whose mission's order has shown no progress for FLEET_ORDER_STALL_SECONDS (its stall clock,
    `dispatch.faults.watch_progress`): a step judges whether the order stalled, as a robot standing still
    sends no state that would wake one."""
    if not settings.DISPATCH_ORDER_STALL_SECONDS:
        return []
    stalled_since = now - timedelta(seconds=settings.DISPATCH_ORDER_STALL_SECONDS)
    return list(
        Mission.objects.filter(state=MissionState.RUNNING, progress_seen_at__lte=stalled_since)
        .values_list("robot", flat=True)
        .distinct()
    )


def _orders_not_taken(missions: QuerySet[Mission]) -> list[str]:
    """The robots of `missions` that lack their mission's order (`order_lacked`)."""
    rows = list(
        missions.values_list("robot", "order_sent_at", KT("order__orderId"), KT("order__orderUpdateId"))
    )
    held = livestate.orders_held([robot for robot, *_ in rows])
    return [
        robot
        for robot, sent_at, order_id, update_id in rows
        if order_lacked(
            held[robot],
            order_id=order_id,
            update_id=-1 if update_id is None else int(update_id),
            sent_at=sent_at,
        )
    ]


def robots_with_missions() -> list[str]:
    """Robots with a running or queued mission."""
    return list(
        Mission.objects.filter(state__in=[MissionState.RUNNING, MissionState.PENDING], robot__isnull=False)
        .values_list("robot", flat=True)
        .distinct()
    )


# --- assignment's reads (`missions.services.missions_assign`, `mission_claim`) ------------------------------

# The unbound queued missions, highest priority first, oldest first among equals; without their trees,
# which `_unbound_missions` reads only for missions it has not seen since they last changed.
UNBOUND_MISSIONS_SQL = f"""
    SELECT name, updated_at, priority, created_at, robot_selector, waiting_reason
    FROM {Mission._meta.db_table}
    WHERE robot IS NULL AND state = '{MissionState.PENDING}' AND lifecycle = '{Lifecycle.ALIVE}'
      AND created_at <= %s
    ORDER BY priority DESC, queue_position LIMIT %s
"""
MISSION_ROUTES_SQL = (
    f"SELECT name, mission_tree, update_nodes FROM {Mission._meta.db_table} WHERE name = ANY(%s)"
)
# A robot may take a mission: online, not in teleop nor charging nor in an operating mode that takes no
# orders (VDA 5050's MANUAL, SERVICE, ...), no FATAL error of its own.
_MAY_WORK_SQL = f"""
    r.online AND r.lifecycle = '{Lifecycle.ALIVE}'
    AND r.state NOT IN ('{RobotState.TELEOP}', '{RobotState.CHARGING}') AND NOT r.switch_teleop
    AND r.operating_mode NOT IN ({", ".join(sorted(f"'{mode.value}'" for mode in MODES_WITHOUT_ORDERS))})
    AND NOT EXISTS (
        SELECT 1 FROM jsonb_each(r.errors) AS e(kind, error)
        WHERE e.error->>'level' = 'FATAL' AND e.error->'references' = '{{}}'::jsonb
    )
"""
# Its battery lets it take a mission: above its critical level, and not due to charge (at or below the
# level at which it charges first, `robot_charge_threshold_sql`): such a robot falls idle and the station
# plan sends it to charge, instead of its next mission taking it down to its critical level.
_BATTERY_OK_SQL = f"r.battery_level >= r.battery_critical_level AND {robot_charge_threshold_sql('r')} IS NULL"
# A robot's abilities, place and whether it may take a mission (`_candidate_robot`'s first columns).
_ROBOT_COLUMNS_SQL = f"""
    r.name, r.labels, r.agv_class, {factsheet_actions_sql("r")},
    r.last_state_at IS NOT NULL, r.pose_x, r.pose_y, r.pose_map_id,
    r.online AND r.lifecycle = '{Lifecycle.ALIVE}', {_MAY_WORK_SQL},
    {_BATTERY_OK_SQL}, r.maps
"""
# Robots with what makes them free or not, and their own queue's head (`QueueHead`, found by
# mission_queue_idx). Whether they are busy is one look at the live missions for them all (`BUSY_ROBOTS_SQL`).
# Followed by a WHERE clause: every robot, or the free ones.
CANDIDATE_ROBOTS_SQL = f"""
    WITH busy AS MATERIALIZED ({BUSY_ROBOTS_SQL})
    SELECT {_ROBOT_COLUMNS_SQL}, r.name IN (SELECT robot FROM busy),
        CASE WHEN r.state = '{RobotState.IDLE}' THEN r.state_since END,
        head.priority, head.created_at
    FROM {Robot._meta.db_table} r
    LEFT JOIN LATERAL (
        SELECT priority, created_at FROM {Mission._meta.db_table} m
        WHERE m.robot = r.name AND m.state = '{MissionState.PENDING}'
        ORDER BY m.priority DESC, m.queue_position LIMIT 1
    ) AS head ON true
"""
FREE_ROBOTS_SQL = f"""{CANDIDATE_ROBOTS_SQL}
    WHERE {_MAY_WORK_SQL} AND {_BATTERY_OK_SQL} AND r.name NOT IN (SELECT robot FROM busy)
"""
# The robot that claims (`missions.services.mission_claim`): its step holds its lock and has just read its
# queue empty, so it is not busy and has no queue head of its own; how long it has been idle only breaks
# ties between robots, and it is alone.
CLAIMANT_SQL = f"""
    SELECT {_ROBOT_COLUMNS_SQL}, false, NULL::timestamptz, NULL::integer, NULL::timestamptz
    FROM {Robot._meta.db_table} r WHERE r.name = %s
"""


def unbound_missions_wait() -> bool:
    return Mission.objects.filter(robot__isnull=True, state=MissionState.PENDING).exists()


@dataclass(frozen=True)
class AssignmentInputs:
    missions: list[UnboundMission]
    robots: list[CandidateRobot]
    waiting_reasons: dict[str, str | None]  # each unbound mission's, as stored


def assignment_inputs(*, free_only: bool) -> AssignmentInputs:
    """The unbound queued missions and the robots (every one, or only the free ones), as assignment's
    records; none of either when there is nothing to bind (no mission, or no free robot)."""
    if free_only:
        robots = _candidate_robots(FREE_ROBOTS_SQL, [])
        if not robots:
            return AssignmentInputs([], [], {})
        missions, waiting_reasons = _unbound_missions(created_before=timezone.now(), limit=None)
        return AssignmentInputs(missions, robots, waiting_reasons)
    missions, waiting_reasons = _unbound_missions(created_before=timezone.now(), limit=None)
    if not missions:
        return AssignmentInputs([], [], {})
    return AssignmentInputs(missions, _candidate_robots(CANDIDATE_ROBOTS_SQL, []), waiting_reasons)


def claim_inputs(*, robot: str, created_before: datetime, limit: int) -> AssignmentInputs:
    """The robot `robot` and the first `limit` unbound missions created before `created_before`, highest
    priority and oldest first: what a robot that just fell free (its queue empty) chooses its next mission
    from."""
    missions, waiting_reasons = _unbound_missions(created_before=created_before, limit=limit)
    if not missions:  # the pool is empty (a fleet of named missions): the robot is not read
        return AssignmentInputs([], [], {})
    robots = _candidate_robots(CLAIMANT_SQL, [robot])
    return AssignmentInputs(missions if robots else [], robots, waiting_reasons)


def _candidate_robots(sql: str, params: list[Any]) -> list[CandidateRobot]:
    with connection.cursor() as cursor:
        cursor.execute(sql, params)
        return [_candidate_robot(*row) for row in cursor.fetchall()]


# The unbound missions read before, as assignment's records, while they do not change (by name: the
# `updated_at` they were read at and the record), the least recently read dropped first. Parsing their trees
# was most of a run's CPU.
_unbound_records: OrderedDict[str, tuple[datetime, UnboundMission]] = OrderedDict()
UNBOUND_RECORDS_KEPT = 20_000


def _unbound_missions(
    *, created_before: datetime, limit: int | None
) -> tuple[list[UnboundMission], dict[str, str | None]]:
    with connection.cursor() as cursor:
        cursor.execute(UNBOUND_MISSIONS_SQL, [created_before, limit])
        rows = cursor.fetchall()
        unseen = [row[0] for row in rows if _unbound_records.get(row[0], (None,))[0] != row[1]]
        routes = {}
        if unseen:
            cursor.execute(MISSION_ROUTES_SQL, [unseen])
            routes = {name: (tree, update_nodes) for name, tree, update_nodes in cursor.fetchall()}
    missions = []
    for name, updated_at, priority, created, selector, _reason in rows:
        if name in routes:
            _unbound_records[name] = (
                updated_at,
                _unbound_mission(name, priority, created, selector, *routes[name]),
            )
        elif name not in _unbound_records:
            continue  # bound or deleted between the two reads
        _unbound_records.move_to_end(name)
        record = _unbound_records[name][1]
        if (record.priority, record.created) != (priority, created):  # a row's changes all touch updated_at,
            record = replace(record, priority=priority, created=created)  # but a test's may not
        missions.append(record)
    while len(_unbound_records) > UNBOUND_RECORDS_KEPT:
        _unbound_records.popitem(last=False)
    return missions, {row[0]: row[5] for row in rows}


def _unbound_mission(
    name: str,
    priority: int,
    created: datetime,
    selector: Any,
    mission_tree: Any,
    update_nodes: Any,
) -> UnboundMission:
    selector = json_column(selector) or {}
    try:
        tree = engine.apply_route_updates(
            engine.parse_tree(json_column(mission_tree)), json_column(update_nodes)
        )
    except engine.TreeError:
        tree = None  # its step fails it once bound
    waypoints = [
        waypoint
        for node in (tree.nodes if tree else ())
        if node.kind == NodeKind.ROUTE
        for waypoint in node.params["waypoints"]
    ]
    start = waypoints[0] if waypoints else None
    return UnboundMission(
        name=name,
        priority=priority,
        created=created,
        selector=RobotSelector(
            labels=frozenset(selector.get("labels", ())),
            robot_types=frozenset(selector.get("robot_types", ())),
            action_types=frozenset(selector.get("action_types", ())),
        ),
        start=None if start is None else Pose(start["x"], start["y"], str(start.get("map_id", ""))),
        maps=frozenset(map_id for map_id in maps.waypoint_map_ids(waypoints) if map_id),
    )


def _candidate_robot(
    name: str,
    labels: Any,
    robot_type: str,
    actions: Any,
    has_pose: bool,
    x: float,
    y: float,
    map_id: str,
    online: bool,
    may_work: bool,
    battery_ok: bool,
    robot_maps: Any,
    busy: bool,
    idle_since: datetime | None,
    head_priority: int | None,
    head_created: datetime | None,
) -> CandidateRobot:
    actions, robot_maps = json_column(actions), json_column(robot_maps)
    return CandidateRobot(
        name=name,
        labels=frozenset(json_column(labels) or ()),
        robot_type=robot_type,
        action_types=None if actions is None else frozenset(a.get("actionType") for a in actions),
        pose=Pose(x, y, map_id) if has_pose else None,
        online=online,
        idle=may_work and not busy,
        battery_ok=battery_ok,
        enabled_maps=(
            frozenset(m["map_id"] for m in robot_maps if m.get("map_status") == MapStatus.ENABLED)
            if robot_maps
            else None
        ),
        idle_since=idle_since,
        queue_head=None if head_created is None else QueueHead(head_priority, head_created),
    )
