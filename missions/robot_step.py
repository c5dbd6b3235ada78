"""Stepping a robot: the dispatch step's I/O around the pure engine (`dispatch.step`).

Under the robot's row lock: load the robot, its running and next missions and its latest live state, run
the pure step, store what it decided (with the messages, numbered and encoded, in the robot's outbox) and
hand back what to publish.
"""

import logging
import threading
from dataclasses import dataclass, field, fields, replace
from datetime import UTC, datetime, timedelta
from enum import Enum, auto
from functools import cache
from typing import Any, NamedTuple

import orjson
from django.conf import settings
from django.db import connection, transaction
from django.db.backends.utils import CursorWrapper
from django.utils import timezone

from dispatch.held import FINAL
from dispatch.records import (
    ActionRecord,
    DispatchSettings,
    MissionRecord,
    Outgoing,
    RobotView,
    StepResult,
    ZoneReach,
)
from dispatch.step import step
from dispatch.zone_sets import ZoneSetMoves, plan_zone_sets
from kit.db import json_column, jsonb, pipelined_transaction
from kit.wake import request_assignment, request_zones_plan
from missions.choices import MissionState
from missions.models import Mission
from missions.rows import (
    MISSION_RECORD_FIELDS,
    RELEASE_SQL,
    ROBOT_QUEUE_LOCK_SQL,
    binding_record,
    binding_time,
    mission_columns,
    mission_db_values,
    mission_records,
    mission_row_delete,
    robot_charge_threshold_sql,
    zone_reach_record,
)
from missions.services import mission_claim
from missions.tuning import OUTBOX_LIMIT
from robots import livestate
from robots.choices import InstantActionsKey, RobotState, SettingSource
from robots.models import InstantAction, Robot
from robots.selectors import robot_unfinished_instant_actions
from robots.services import robot_rows_delete
from vda5050 import compat
from vda5050.codec import encode, header_for, parse_state
from vda5050.errors import ProtocolError
from vda5050.models import State
from vda5050.topics import RobotAddress, Topic
from vda5050.versions import V3_0
from vda5050.zones import ZoneType
from zones.models import ZoneReach as ZoneReachRow
from zones.models import ZoneSet
from zones.selectors import zone_set_messages

logger = logging.getLogger(__name__)

# The step's reads are the hot path of the whole system. As plain SQL with only the columns the step needs,
# read straight into the engine's records, they skip the ORM's compiler and model instances (which cost
# more than the queries) and never read what the step does not use, such as a robot's factsheet. Both
# lock what they read until the step commits. A robot's next mission is its queue's highest-priority one,
# the first queued among equals (a running one is never preempted: it comes first whatever its priority).
_FINAL_ACTION_STATUSES_SQL = ", ".join(f"'{status}'" for status in sorted(FINAL))
# The maps with an enabled RELEASE zone, read only for a robot without a zone reach (the zone plan has not
# seen it yet): on those, its orders are held back as if its reach allowed nothing (`_may_be_on`).
ZONED_MAPS_SQL = f"""
    SELECT s.map_id FROM {ZoneSet._meta.db_table} s
    WHERE s.enabled AND jsonb_path_exists(s.zones, '$[*] ? (@.zone_type == "{ZoneType.RELEASE}")')
"""
# The fleet's enabled zone set of each map (mapId -> zoneSetId) for a robot that takes zone sets; NULL for
# the others, which read nothing more.
ZONE_SETS_ENABLED_SQL = f"""
    CASE WHEN r.protocol_version = '{V3_0}' AND r.supported_zones <> '[]'::jsonb THEN (
        SELECT COALESCE(jsonb_object_agg(z.map_id, z.name), '{{}}'::jsonb)
        FROM {ZoneSet._meta.db_table} z WHERE z.enabled
    ) END
"""
ROBOT_FOR_STEP_SQL = f"""
    SELECT r.lifecycle, r.state, r.online, r.battery_critical_level, r.switch_teleop, r.instant_actions_key,
        r.instant_actions_key_source = '{SettingSource.OPERATOR}',
        NOT r.compatibility_rules @> '[{{"rule": "{compat.Rule.ORDER_UPDATE_NOT_EXECUTED}"}}]'::jsonb,
        r.next_order_header_id, r.next_instant_actions_header_id, r.next_zone_set_header_id,
        r.next_responses_header_id, r.outbox,
        {ZONE_SETS_ENABLED_SQL}, r.zone_set_moves, r.zone_set_moved_at,
        r.interface_name, r.manufacturer, r.serial_number, r.protocol_version,
        {robot_charge_threshold_sql("r")},
        EXISTS (
            SELECT 1 FROM {InstantAction._meta.db_table} a
            WHERE a.robot_id = r.name
              AND (a.status IS NULL OR a.status NOT IN ({_FINAL_ACTION_STATUSES_SQL}))
        ),
        z.robot IS NOT NULL, z.order_id, z.release_through, z.waiting, z.responses, z.responses_version,
        z.responses_sent,
        CASE WHEN z.robot IS NULL THEN ARRAY({ZONED_MAPS_SQL}) END
    FROM {Robot._meta.db_table} r LEFT JOIN {ZoneReachRow._meta.db_table} z ON z.robot = r.name
    WHERE r.name = %s FOR UPDATE OF r
"""
CURRENT_MISSIONS_SQL = f"""
    SELECT {", ".join(mission_columns(MISSION_RECORD_FIELDS))} FROM {Mission._meta.db_table}
    WHERE robot = %s AND state IN ('{MissionState.RUNNING}', '{MissionState.PENDING}')
    ORDER BY state <> '{MissionState.RUNNING}', priority DESC, queue_position LIMIT %s FOR UPDATE
"""
# The fields a step writes; the record's others are the mission's spec.
STEP_STATUS_FIELDS = (
    "state",
    "current_node",
    "node_status",
    "task_status",
    "start_timestamp",
    "end_timestamp",
    "failure_reason",
    "failure_category",
    "waiting_reason",
    "order",
    "order_sent_at",
    "order_accepted",
    "attempts",
    "progress",
    "progress_seen_at",
)


class WireMessage(NamedTuple):
    """A message for the robot as it goes on the wire: its topic, headerId and encoded bytes."""

    topic: Topic
    header_id: int
    payload: bytes


@dataclass
class StepOutcome:
    """What a step decided that happens outside the database: messages to publish, notify nodes to run."""

    address: RobotAddress | None = None
    instant_actions_key: str = "actions"
    messages: list[Outgoing] = field(default_factory=list)
    notifies: list[tuple[str, str]] = field(default_factory=list)
    finished: list[MissionRecord] = field(default_factory=list)
    rejections: int = 0
    released: list[str] = field(default_factory=list)  # missions given back to assignment
    zones_plan: bool = False  # the zone plan should run (`StepResult.zones_plan`)
    header_ids: list[int] = field(default_factory=list)  # the messages', drawn in the step's transaction
    # What to publish, in this order: `messages` encoded, after those of an earlier step that may not
    # have gone out (`_wire_messages`).
    wire: list[WireMessage] = field(default_factory=list)


def robot_step(*, name: str, now: datetime | None = None) -> StepOutcome:
    """Advance robot `name`: its instant actions, its running mission, and the next ones in its queue.

    Runs under the robot's row lock, so steps of one robot are serialized across workers; everything it
    decides is stored before the caller publishes, so a crash in between only delays a (re)send. The
    messages' headerIds are drawn in the same transaction, from counters on the robot's row, and the
    messages kept there until a later step knows they went out (`_wire_messages`). A mission queued while
    the step ended the robot's last one gets a transaction more (QUEUE_GREW_SQL), at once: a step
    requested instead would wait behind every other robot's.
    """
    outcome = StepOutcome()
    while _robot_step_transaction(name, now or timezone.now(), outcome):
        pass
    return outcome


def _robot_step_transaction(name: str, now: datetime, outcome: StepOutcome) -> bool:
    """One transaction of a step, adding to `outcome`; True if the robot needs another one."""
    first, released = len(outcome.messages), len(outcome.released)
    # Open across the transaction: the look at the queue is read once it has committed, from the reply
    # that also brings the COMMIT's (reading it inside would cost a round trip of its own).
    with (
        connection.cursor() as outbox_cursor,
        connection.cursor() as lock_cursor,
        connection.cursor() as queue_cursor,
    ):
        with pipelined_transaction():
            end, wire = _robot_step_locked(name, now, outcome)
            if end is StepEnd.ROBOT_DELETED:
                outcome.messages.clear()  # the robot is gone: nothing more is sent to it
            elif wire is not None:
                _wire_messages(outbox_cursor, name, wire, outcome, first)
            if end is StepEnd.QUEUE_RAN_DRY:
                lock_cursor.execute(ROBOT_QUEUE_LOCK_SQL, [name])
                queue_cursor.execute(QUEUE_GREW_SQL, [name])
        if len(outcome.released) > released:
            request_assignment()  # committed: another robot may take them
        if outcome.zones_plan:
            outcome.zones_plan = False
            request_zones_plan()  # committed: the plan reads what the step wrote
        if end is StepEnd.ROBOT_DELETED:  # its live state goes once that is committed
            outcome.header_ids.clear()
            outcome.wire.clear()
            transaction.on_commit(lambda: livestate.forget(name))
            return False
        if end is not StepEnd.QUEUE_RAN_DRY:
            return False
        queue_grew, unbound_wait = queue_cursor.fetchone()
        if unbound_wait:
            _unbound_seen.set()
        if not queue_grew and unbound_wait:
            request_assignment()  # the robot is free: an unbound mission it could not claim may be its
        return queue_grew


@dataclass
class _RobotWire:
    """What a step transaction read of the robot's messages: the next headerId on each topic, the outbox
    (the latest messages it was given, as `_wire_messages` stores them), and the headerId last published
    on each topic as far as Redis knows."""

    next_header_ids: dict[Topic, int]
    outbox: list[dict[str, Any]]
    published: dict[str, int]
    responses_version: int = 0  # the zone plan's answers the robot's responses go out with


OUTBOX_SQL = f"""
    UPDATE {Robot._meta.db_table}
    SET next_order_header_id = %s, next_instant_actions_header_id = %s, next_zone_set_header_id = %s,
        next_responses_header_id = %s, outbox = %s
    WHERE name = %s
"""


# Which of the zone plan's answers went out lives on the robot's zone reach (`missions.zone_plan`); the
# responses topic's headerIds, like every topic's, on the robot: a reach is deleted and made anew when zones
# come and go, and a headerId must never go back (the robot, and Redis's publish claims, would drop them).
RESPONSES_SENT_SQL = f"""
    UPDATE {ZoneReachRow._meta.db_table} SET responses_sent = %s WHERE robot = %s
"""


def _wire_messages(
    cursor: CursorWrapper, name: str, wire: _RobotWire, outcome: StepOutcome, first: int
) -> None:
    """Number and encode the transaction's new messages, keep them in the robot's outbox with those of its
    earlier steps that Redis does not know to be published, and put all of those on `outcome.wire`.

    A process killed between a step's COMMIT and its publish would otherwise leave its headerIds unsent
    for ever: the next step sends them first, identical to the byte. One whose publish is only in flight
    sends it itself: the publisher claims each headerId in Redis first (`workers.publish`), so a message
    goes out once. Once Redis lost the robot's marks (a restart), only the newest message on each topic is
    sent again: an older one could hand the robot an order its mission has moved past, while the newest is
    still what the robot should have (a duplicate of it, if it went out, is identical).
    """
    unsent = _maybe_unsent(wire)
    new = []
    stamped_at = datetime.now(UTC)
    assert outcome.address is not None  # set by the step that read `wire`
    for message in outcome.messages[first:]:
        header_id = wire.next_header_ids[message.topic]
        wire.next_header_ids[message.topic] += 1
        header = header_for(outcome.address, header_id=header_id, at=stamped_at)
        payload = encode(message.content, header, instant_actions_key=outcome.instant_actions_key)
        new.append({"topic": message.topic.value, "header_id": header_id, "payload": payload.decode()})
        outcome.header_ids.append(header_id)
    if any(message.topic == Topic.RESPONSES for message in outcome.messages[first:]):
        cursor.execute(RESPONSES_SENT_SQL, [wire.responses_version, name])
    if new:
        cursor.execute(
            OUTBOX_SQL,
            [
                wire.next_header_ids[Topic.ORDER],
                wire.next_header_ids[Topic.INSTANT_ACTIONS],
                wire.next_header_ids[Topic.ZONE_SET],
                wire.next_header_ids[Topic.RESPONSES],
                jsonb((unsent + new)[-OUTBOX_LIMIT:]),
                name,
            ],
        )
    queued = {(message.topic, message.header_id) for message in outcome.wire}
    for entry in unsent + new:
        topic = Topic(entry["topic"])
        if (topic, entry["header_id"]) not in queued:  # a step's second transaction reads the first's
            outcome.wire.append(WireMessage(topic, entry["header_id"], entry["payload"].encode()))


def _maybe_unsent(wire: _RobotWire) -> list[dict[str, Any]]:
    """The outbox's messages that may not have gone out (`_wire_messages`), oldest first."""
    if wire.published:
        return [e for e in wire.outbox if e["header_id"] > wire.published.get(e["topic"], -1)]
    newest = {entry["topic"]: entry for entry in wire.outbox}  # the outbox is in headerId order per topic
    return [entry for entry in wire.outbox if newest[entry["topic"]] is entry]


# Whether this process's steps lately saw unbound missions waiting: only then does a step that ends a robot's
# last mission try to claim one in its transaction (`mission_claim`), so that a fleet of named missions pays
# no round trip for it. The look at the queue after such a step's commit sets it again.
_unbound_seen = threading.Event()


class StepEnd(Enum):
    """What a step's transaction left behind, for what the step does before and after its COMMIT."""

    SETTLED = auto()  # a mission runs or waits, the robot had none, or there is no robot of that name
    QUEUE_RAN_DRY = auto()  # the step ended the robot's last mission: its queue was empty when last read
    ROBOT_DELETED = auto()


# Whether the robot has a queued mission, read under the robot's queue lock (ROBOT_QUEUE_LOCK_SQL) by a step
# that ended the robot's last mission; and whether unbound missions wait (the robot, free, may take one).
QUEUE_GREW_SQL = f"""
    SELECT EXISTS (
        SELECT 1 FROM {Mission._meta.db_table} WHERE robot = %s AND state = '{MissionState.PENDING}'
    ), EXISTS (
        SELECT 1 FROM {Mission._meta.db_table} WHERE robot IS NULL AND state = '{MissionState.PENDING}'
    )
"""


def _robot_step_locked(name: str, now: datetime, outcome: StepOutcome) -> tuple[StepEnd, _RobotWire | None]:
    """The step inside its transaction, from taking the robot's row lock on, adding to `outcome`; also
    what it read of the robot's messages (None if there is no robot of that name)."""
    with connection.cursor() as robot_cursor, connection.cursor() as missions_cursor:
        robot_cursor.execute(ROBOT_FOR_STEP_SQL, [name])
        # The running mission and the next queued one: a step that ends a mission usually starts the next.
        missions_cursor.execute(CURRENT_MISSIONS_SQL, [name, 2])
        row = robot_cursor.fetchone()
        upcoming = mission_records(missions_cursor.fetchall())
    # Fewer than asked: the whole queue is read, and is not read again once these end (a mission queued since
    # is the look after the commit's, QUEUE_GREW_SQL).
    queue_read_whole = len(upcoming) < 2
    if row is None:
        return StepEnd.SETTLED, None
    (
        lifecycle,
        robot_state,
        online,
        critical_level,
        switch_teleop,
        actions_key,
        actions_key_by_operator,
        routes_ahead,
        next_order_header_id,
        next_instant_actions_header_id,
        next_zone_set_header_id,
        next_responses_header_id,
        outbox,
        zone_sets_enabled,
        zone_set_moves,
        zone_set_moved_at,
        *address,
        charge_threshold,
        has_actions,
        has_reach,
        reach_order_id,
        release_through,
        waiting,
        responses,
        responses_version,
        responses_sent,
        zoned_maps,
    ) = row
    outcome.address = RobotAddress(*address)
    outcome.instant_actions_key = actions_key
    state, state_arrived_at, published = _live_state(name)
    wire = _RobotWire(
        {
            Topic.ORDER: next_order_header_id,
            Topic.INSTANT_ACTIONS: next_instant_actions_header_id,
            Topic.ZONE_SET: next_zone_set_header_id,
            Topic.RESPONSES: next_responses_header_id,
        },
        orjson.loads(outbox) if outbox is not None else [],
        published,
        responses_version or 0,
    )
    zone_reach = None
    if has_reach:
        due = responses_version > responses_sent
        zone_reach = zone_reach_record(reach_order_id, release_through, waiting, responses, due=due)
    elif zoned_maps and _may_be_on(state, zoned_maps):
        zone_reach = ZoneReach()  # not seen by the zone plan yet: a new order releases its start alone
    actions = [_action_record(a) for a in robot_unfinished_instant_actions(robot=name)] if has_actions else []
    if zone_sets_enabled is not None:
        moves = ZoneSetMoves(json_column(zone_set_moves), zone_set_moved_at)
        actions += _distribute_zone_sets(
            name, json_column(zone_sets_enabled), moves, state, online, actions, now, outcome
        )
    view = RobotView(
        name=name,
        lifecycle=lifecycle,
        state=robot_state,
        online=online,
        battery_critical_level=critical_level,
        charge_threshold=charge_threshold,
        switch_teleop=switch_teleop,
        instant_actions_key=actions_key,
        instant_actions_key_by_operator=actions_key_by_operator,
        routes_ahead=routes_ahead,
        zone_reach=zone_reach,
    )
    ended_a_mission = False
    claimed: MissionRecord | None = None  # an unbound mission the step claimed, as stored: still unbound
    while True:
        mission = upcoming.pop(0) if upcoming else None
        result = step(
            now=now,
            robot=view,
            state=state,
            state_arrived_at=state_arrived_at,
            mission=mission,
            actions=actions,
            settings=dispatch_settings(),
        )
        _store_actions(name, actions, result.actions)
        actions = [a for a in result.actions if a.status not in FINAL]
        _store_compatibility(name, result, now)
        if result.instant_actions_key is not None:
            outcome.instant_actions_key = result.instant_actions_key
            view = replace(view, instant_actions_key=result.instant_actions_key)
        outcome.messages.extend(result.messages)
        outcome.rejections += int(result.rejected)
        outcome.zones_plan = outcome.zones_plan or result.zones_plan
        if zone_reach is not None and zone_reach.responses_due:
            view = replace(view, zone_reach=replace(zone_reach, responses_due=False))  # sent once a step
        view = replace(view, state=result.robot_state)
        if mission is not None and result.mission is not None:
            # A claimed mission is bound with its first write (`mission_claim`).
            bound = claimed is not None and claimed.name == mission.name
            stored, bind_to = (claimed, name) if bound else (mission, None)
            for passed in result.passed:  # each its own write, for the change feed: a leaf seen RUNNING
                _store_mission(stored, passed, bind_to=bind_to)
                stored, bind_to = passed, None
            _store_mission(stored, result.mission, bind_to=bind_to)
            if result.notify is not None:
                outcome.notifies.append((mission.name, result.notify))
            if result.mission.done:
                outcome.finished.append(result.mission)
            if result.delete_mission:
                mission_row_delete(mission.name)
            if result.release is not None:
                _release(name, mission.name, result.release)
                outcome.released.append(mission.name)
        if result.delete_robot:
            robot_rows_delete(name)
            return StepEnd.ROBOT_DELETED, wire
        if mission is None or not (result.mission.done or result.delete_mission):
            break
        ended_a_mission = True
        if not (upcoming or queue_read_whole):
            upcoming = _current_missions(name, count=2)
        # Its next may be an unbound one, unless it ended the mission not idle (charging, in teleop).
        if not upcoming and view.state == RobotState.IDLE and _unbound_seen.is_set():
            claimed = mission_claim(robot=name)
            if claimed is not None:  # the step runs it as bound to the robot, and binds it when it stores it
                binding = [*claimed.assignment, binding_record(name, now)]
                upcoming = [replace(claimed, assignment=binding, waiting_reason=None)]
            else:
                _unbound_seen.clear()  # until the look at the queue after the commit sees some again
    if view.state != robot_state:
        changed_at = timezone.now()
        Robot.objects.filter(name=name).update(
            state=view.state, state_since=changed_at, updated_at=changed_at
        )
    return StepEnd.QUEUE_RAN_DRY if mission is None and ended_a_mission else StepEnd.SETTLED, wire


ZONE_SET_MOVES_SQL = f"""
    UPDATE {Robot._meta.db_table} SET zone_set_moves = %s, zone_set_moved_at = %s WHERE name = %s
"""


def _distribute_zone_sets(
    name: str,
    enabled: dict[str, str],
    moves: ZoneSetMoves,
    state: State | None,
    online: bool,
    actions: list[ActionRecord],
    now: datetime,
    outcome: StepOutcome,
) -> list[ActionRecord]:
    """The robot's next zone set moves (`dispatch.zone_sets`): its `zoneSet` messages go on `outcome`, its
    new instant actions are stored and returned (the step sends them with the others), and the moves are
    remembered if they changed."""
    plan = plan_zone_sets(
        robot=name,
        enabled=enabled,
        moves=moves,
        state=state,
        online=online,
        actions=actions,
        now=now,
        resend=dispatch_settings().instant_action_resend,
    )
    if plan.send:
        outcome.messages.extend(Outgoing(message) for message in zone_set_messages(names=plan.send))
    _store_actions(name, [], plan.actions)
    if plan.moves is not moves:
        with connection.cursor() as cursor:
            cursor.execute(ZONE_SET_MOVES_SQL, [jsonb(dict(plan.moves.made)), plan.moves.at, name])
    return plan.actions


def _release(robot: str, mission: str, reason: str) -> None:
    """Unbind the mission assignment bound to the robot (`StepResult.release`)."""
    now = timezone.now()
    with connection.cursor() as cursor:
        cursor.execute(RELEASE_SQL, [now, binding_time(now), reason, mission, robot])


def _current_missions(robot: str, *, count: int) -> list[MissionRecord]:
    """The robot's RUNNING mission, then its queue by priority (highest first), FIFO among equals, locked."""
    with connection.cursor() as cursor:
        cursor.execute(CURRENT_MISSIONS_SQL, [robot, count])
        return mission_records(cursor.fetchall())


def dispatch_settings() -> DispatchSettings:
    return DispatchSettings(
        order_resend=timedelta(seconds=settings.DISPATCH_ORDER_RESEND_SECONDS),
        instant_action_resend=timedelta(seconds=settings.DISPATCH_INSTANT_ACTION_RESEND_SECONDS),
        start_deviation_xy=settings.DISPATCH_START_NODE_DEVIATION,
        order_stall=timedelta(seconds=settings.DISPATCH_ORDER_STALL_SECONDS),
    )


def _may_be_on(state: State | None, maps: list[str]) -> bool:
    """The robot is on one of `maps`, or does not say where it is (then it may be)."""
    position = state.agv_position if state is not None else None
    return position is None or position.map_id in maps


def _live_state(name: str) -> tuple[State | None, datetime | None, dict[str, int]]:
    """The robot's latest state, when it arrived, and the headerIds last published to it (per topic)."""
    payload, arrived_at, published = livestate.state_for_step(name)
    if payload is None:
        return None, None, published
    try:
        return parse_state(payload), arrived_at, published
    except ProtocolError:  # the bridge only stores states it could parse; a stale format is not fatal
        logger.warning("stored state of robot %s no longer parses", name)
        return None, None, published


def _store_mission(before: MissionRecord, after: MissionRecord, *, bind_to: str | None = None) -> None:
    """Write the fields the step changed, in one UPDATE; with `bind_to`, also the binding of the unbound
    mission `before` to that robot (`after.assignment` records it)."""
    changed = {
        name: getattr(after, name)
        for name in STEP_STATUS_FIELDS
        if getattr(before, name) != getattr(after, name)
    }
    if bind_to is not None:
        changed |= {"robot": bind_to, "assignment": after.assignment}
    if not changed:
        return
    values = {**changed, "updated_at": timezone.now()}
    with connection.cursor() as cursor:
        cursor.execute(_mission_update_sql(tuple(values)), [*mission_db_values(values), after.name])


@cache
def _mission_update_sql(columns: tuple[str, ...]) -> str:
    assignments = ", ".join(f"{column} = %s" for column in mission_columns(columns))
    return f"UPDATE {Mission._meta.db_table} SET {assignments} WHERE name = %s"


COMPATIBILITY_SQL = f"""
    UPDATE {Robot._meta.db_table}
    SET compatibility_rules = compatibility_rules || COALESCE((
            SELECT jsonb_agg(new.rule) FROM jsonb_array_elements(%s::jsonb) AS new(rule)
            WHERE NOT compatibility_rules @> jsonb_build_array(jsonb_build_object('rule', new.rule->'rule'))
        ), '[]'::jsonb),
        instant_actions_key = COALESCE(%s::varchar, instant_actions_key),
        instant_actions_key_source = CASE WHEN %s::varchar IS NULL THEN instant_actions_key_source
            ELSE '{SettingSource.LEARNED}' END,
        updated_at = %s
    WHERE name = %s
"""


def _store_compatibility(name: str, result: StepResult, now: datetime) -> None:
    """Record the compatibility rules the step applied (each rule once per robot: when it first applied)
    and the instant actions key it learned."""
    if not result.rules_applied:
        return
    key = result.instant_actions_key
    assert key is None or key in InstantActionsKey.values
    at = now.isoformat()
    rules = [{"rule": rule.value, "applied_at": at, "reason": why} for rule, why in result.rules_applied]
    for rule, why in result.rules_applied:
        logger.warning("robot %s: compatibility rule %s applied: %s", name, rule.value, why)
    with connection.cursor() as cursor:
        cursor.execute(COMPATIBILITY_SQL, [jsonb(rules), key, key, timezone.now(), name])


def _action_record(action: InstantAction) -> ActionRecord:
    return ActionRecord(**{f.name: getattr(action, f.name) for f in fields(ActionRecord)})


# The step's writes are plain SQL: the ORM's bulk writes and deletes open transaction blocks of their own,
# which `pipelined_transaction` does not allow.
UPSERT_ACTIONS_SQL = f"""
    INSERT INTO {InstantAction._meta.db_table}
        (action_id, robot_id, action_type, mission, status, sent_at, send_count, parameters, created_at)
    SELECT *, %s FROM unnest(
        %s::varchar[], %s::varchar[], %s::varchar[], %s::varchar[], %s::varchar[], %s::timestamptz[],
        %s::integer[], %s::jsonb[]
    )
    ON CONFLICT (action_id) DO UPDATE
    SET status = EXCLUDED.status, sent_at = EXCLUDED.sent_at, send_count = EXCLUDED.send_count
"""


def _store_actions(robot: str, before: list[ActionRecord], after: list[ActionRecord]) -> None:
    """Insert new instant actions and save the ones whose status or send time changed, in one statement."""
    known = {a.action_id: a for a in before}
    changed = [a for a in after if known.get(a.action_id) != a]
    if not changed:
        return
    with connection.cursor() as cursor:
        cursor.execute(
            UPSERT_ACTIONS_SQL,
            [
                timezone.now(),
                [a.action_id for a in changed],
                [robot] * len(changed),
                [a.action_type for a in changed],
                [a.mission for a in changed],
                [a.status for a in changed],
                [a.sent_at for a in changed],
                [a.send_count for a in changed],
                [None if a.parameters is None else jsonb(a.parameters) for a in changed],
            ],
        )
