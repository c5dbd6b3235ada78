"""Changes to missions. Each runs in one transaction, locks the row it changes, and wakes the dispatch engine
for the mission's robot (after commit) so that the engine reacts to the change.

Invariant kept here: a PENDING mission never has needs_canceled set; canceling it ends it at once, so the
engine only ever cancels RUNNING missions.
"""

import logging
from collections.abc import Mapping
from contextlib import nullcontext
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.db import IntegrityError, connection, transaction
from django.utils import timezone

from access.choices import WriteAction
from access.models import WriteRecord
from access.services import write_record, writes_via_now
from dispatch.assignment import NOT_YET_ASSIGNED, assign, burst_hold, choices_of
from dispatch.ending import DEADLINE_PASSED
from dispatch.engine import ROOT, Tree, TreeError, initial_node_status, parse_tree, set_leaf_state
from dispatch.records import MissionRecord
from kit.api.errors import ObjectError, UsageError
from kit.api.names import object_name_check, object_name_for_create
from kit.api.rows import lock_row
from kit.wake import request_assignment, request_steps
from missions.choices import DONE_STATES, FailureCategory, Lifecycle, MissionState, NodeKind
from missions.models import Mission
from missions.rows import (
    MISSION_FIELDS,
    MISSION_RECORD_FIELDS,
    RELEASE_ORPHANS_SQL,
    ROBOT_DELETED,
    binding_time,
    mission_columns,
    mission_db_values,
    mission_records,
    mission_row_delete,
    robot_busy_sql,
)
from missions.selectors import assignment_inputs, claim_inputs
from missions.tuning import CLAIM_PAGE, CLAIM_TRIES
from robots.models import Robot

logger = logging.getLogger(__name__)

# A mission's priority: higher first in a robot's queue and in assignment.
PRIORITY_MIN, PRIORITY_MAX = -1000, 1000
# Mission states in which routes may still be updated.
UPDATABLE_STATES = frozenset({MissionState.PENDING, MissionState.RUNNING})
# Fields a cancel writes.
CANCEL_FIELDS = ("state", "end_timestamp", "failure_category", "needs_canceled", "node_status")


def mission_create(*, actor: str, name: str | None, prefix: str | None, spec: Mapping[str, Any]) -> Mission:
    """A new PENDING mission, queued behind the robot's other missions (the robot need not exist yet), or,
    without a robot, unbound: assignment (`missions_assign`) binds it to a free capable robot.

    `spec` is in the API's shape (robot, mission_tree, timeout, deadline, needs_canceled, update_nodes,
    priority, robot_selector).
    The tree is stored normalized: every node named (unnamed ones by their index) with its parent and its
    one kind. A mission created with needs_canceled is created CANCELED. `actor` (who asks, as in every
    service here) is recorded with the write.
    """
    mission_name = object_name_for_create(name=name, prefix=prefix, what="Mission name")
    robot = spec.get("robot")
    selector = spec.get("robot_selector")
    if robot is not None:
        object_name_check(robot, what="Robot name")
        if selector is not None:
            raise UsageError("Only a mission without robot has a robot_selector.")
    tree = _tree_parse(spec["mission_tree"])
    mission = Mission(
        name=mission_name,
        robot=robot,
        priority=spec.get("priority", 0),
        robot_selector=None if selector is None else _plain(selector),
        purpose=spec.get("purpose"),  # only the dispatch core's trips have one (missions.trips)
        mission_tree=[
            {"name": node.name, "parent": node.parent, node.kind: node.params} for node in tree.nodes
        ],
        timeout=spec.get("timeout", Mission._meta.get_field("timeout").get_default()),
        deadline=spec.get("deadline"),
        node_status=initial_node_status(tree),
        waiting_reason=NOT_YET_ASSIGNED if robot is None else None,
    )
    update_nodes = spec.get("update_nodes")
    if update_nodes is not None:
        _route_updates_check(mission, tree, update_nodes)
        mission.update_nodes = _plain(update_nodes)
    if spec.get("needs_canceled"):
        _cancel_queued(mission)
    try:
        queued_behind_others = _mission_insert(mission, actor=actor)
    except IntegrityError as error:
        raise ObjectError.exists("mission", mission_name) from error
    if mission.robot is None:
        if mission.state == MissionState.PENDING:
            request_assignment(defer_while_busy=True)
    elif not queued_behind_others:
        request_steps([mission.robot])
    return mission


def _mission_insert(mission: Mission, *, actor: str) -> bool:
    """Insert the new mission and its WriteRecord (plain SQL, see MISSION_INSERT_SQL); True if it is queued
    behind others.

    Queued behind others: the robot has an earlier unfinished mission, so the step that ends that one starts
    this one (ROBOT_QUEUE_LOCK_SQL keeps that true while a step ends that mission). One statement in
    autocommit mode: one round trip, and the transaction ends on the server without waiting for the API.
    """
    # pre_save: what Model.save() writes, auto_now(_add) timestamps included (set on `mission` too).
    values = mission_db_values(
        {name: MISSION_FIELDS[name].pre_save(mission, True) for name in MISSION_INSERT_FIELDS}
    )
    # Inside a caller's transaction, a savepoint keeps a duplicate name from aborting it.
    with (
        nullcontext() if transaction.get_autocommit() else transaction.atomic(),
        connection.cursor() as cursor,
    ):
        record = [actor, WriteAction.MISSION_CREATE.value, writes_via_now()]
        cursor.execute(MISSION_INSERT_SQL, [*values, *record])
        mission.queue_position, queued_behind_others = cursor.fetchone()
    # What Model.save() records: the instance is now a stored row.
    mission._state.adding = False
    mission._state.db = connection.alias
    return queued_behind_others


def mission_cancel(*, actor: str, mission: Mission) -> Mission:
    """Cancel a mission: a queued one is CANCELED at once; a RUNNING one gets needs_canceled, and the engine
    sends the robot cancelOrder and ends it when the robot confirms. A finished mission is a UsageError."""
    with transaction.atomic():
        locked = lock_row(mission)
        if locked.state == MissionState.CANCELED:
            raise UsageError(f"Mission {locked.name} is already canceled.")
        if locked.state in DONE_STATES:
            raise UsageError(f"{locked.state.capitalize()} mission {locked.name} can't be canceled.")
        if locked.state == MissionState.PENDING:
            _cancel_queued(locked)
        else:
            locked.needs_canceled = True
        locked.save(update_fields=[*CANCEL_FIELDS, "updated_at"])
        write_record(actor=actor, action=WriteAction.MISSION_CANCEL, object_name=locked.name)
        _wake(locked)
    return locked


def mission_delete(*, actor: str, mission: Mission) -> Mission | None:
    """Mark the mission PENDING_DELETE and remove it, at once unless it is RUNNING: then it is canceled
    (needs_canceled) and the engine removes it when it ends. Returns the mission while it remains, else None.
    """
    with transaction.atomic():
        locked = lock_row(mission)
        write_record(actor=actor, action=WriteAction.MISSION_DELETE, object_name=locked.name)
        _wake(locked)
        if locked.state == MissionState.RUNNING:
            locked.lifecycle = Lifecycle.PENDING_DELETE
            locked.needs_canceled = True
            locked.save(update_fields=["lifecycle", "needs_canceled", "updated_at"])
            return locked
        mission_row_delete(locked.name)
    return None


def mission_update_routes(
    *, actor: str, mission: Mission, update_nodes: Mapping[str, Mapping[str, Any]]
) -> Mission:
    """Give route nodes new waypoints (merged into update_nodes); the engine re-sends a running route.

    Only while the mission is PENDING or RUNNING, only route nodes, and only nodes that are not done.
    """
    with transaction.atomic():
        locked = lock_row(mission)
        if locked.state not in UPDATABLE_STATES:
            raise UsageError(f"Mission {locked.name} is finished with status {locked.state}.")
        _route_updates_check(locked, _tree_parse(locked.mission_tree), update_nodes)
        locked.update_nodes = {**(locked.update_nodes or {}), **_plain(update_nodes)}
        locked.save(update_fields=["update_nodes", "updated_at"])
        write_record(actor=actor, action=WriteAction.MISSION_UPDATE, object_name=locked.name)
        _wake(locked)
    return locked


def mission_prioritize(*, actor: str, mission: Mission, priority: int) -> Mission:
    """Give a queued mission a new priority (within PRIORITY_MIN..PRIORITY_MAX): its place in its robot's
    queue, or in assignment's, follows. A running or finished mission keeps its own (a UsageError)."""
    if not PRIORITY_MIN <= priority <= PRIORITY_MAX:
        raise UsageError(f"Priority must be within {PRIORITY_MIN}..{PRIORITY_MAX}, not {priority}.")
    with transaction.atomic():
        locked = lock_row(mission)
        if locked.state != MissionState.PENDING:
            raise UsageError(f"Mission {locked.name} is {locked.state}: only a queued one changes priority.")
        locked.priority = priority
        locked.save(update_fields=["priority", "updated_at"])
        write_record(actor=actor, action=WriteAction.MISSION_UPDATE, object_name=locked.name)
        if locked.robot is None:
            request_assignment()
        else:
            _wake(locked)
    return locked


def _wake(mission: Mission) -> None:
    """Step the mission's robot; an unbound mission has none to step (assignment reads it afresh)."""
    if mission.robot is not None:
        request_steps([mission.robot])


def _tree_parse(mission_tree: list[Mapping[str, Any]]) -> Tree:
    """The mission tree checked to be one the engine can run, with valid node names."""
    if not mission_tree:
        raise UsageError("Number of nodes must be >= 1")
    try:
        tree = parse_tree([_plain(node) for node in mission_tree])
    except TreeError as error:
        raise UsageError(str(error)) from error
    for node in tree.nodes:
        object_name_check(node.name, what="MissionNode name")
    return tree


def _route_updates_check(mission: Mission, tree: Tree, update_nodes: Mapping[str, Any]) -> None:
    """Refuse updates of nodes that do not exist, are not routes, or are done in a running mission."""
    nodes = {node.name: node for node in tree.nodes}
    for name in update_nodes:
        node = nodes.get(name)
        if node is None:
            raise UsageError(f"Node {name} does not exist in mission {mission.name}")
        if node.kind != NodeKind.ROUTE:
            raise UsageError(
                f"Node {name} of mission {mission.name} is a {node.kind} node; only routes can be updated."
            )
        node_state = mission.node_status.get(name, {}).get("state")
        if mission.state == MissionState.RUNNING and node_state in DONE_STATES:
            raise UsageError(f"Mission node {name} is finished with status {node_state}.")


def _cancel_queued(mission: Mission) -> None:
    """End a mission that never started: CANCELED, its root too; its nodes stay PENDING."""
    mission.state = MissionState.CANCELED
    mission.end_timestamp = timezone.now()
    mission.failure_category = FailureCategory.CANCELED
    mission.needs_canceled = True
    mission.node_status = {**mission.node_status, ROOT: {"state": MissionState.CANCELED, "error_msg": None}}


def _plain(value: Any) -> Any:
    """`value` with validated data's OrderedDicts turned into plain dicts, as stored in JSON fields."""
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_plain(item) for item in value]
    return value


def mission_notify_finished(*, mission: str, node: str, success: bool, error_msg: str | None) -> None:
    """Record a notify node's result and step its robot; a result for a node no longer running is dropped."""
    with transaction.atomic():
        locked = Mission.objects.select_for_update().filter(name=mission).first()
        if locked is None or locked.state != MissionState.RUNNING:
            return
        if locked.node_status.get(node, {}).get("state") != MissionState.RUNNING:
            return
        state = MissionState.COMPLETED if success else MissionState.FAILED
        locked.node_status = set_leaf_state(locked.node_status, node, state, error_msg)
        if not success:
            locked.failure_reason = error_msg
        locked.save(update_fields=["node_status", "failure_reason", "updated_at"])
        _wake(locked)


# queue_position is left to its database default: the next value of the queue sequence (NextQueuePosition).
MISSION_INSERT_FIELDS = tuple(name for name, field in MISSION_FIELDS.items() if not field.has_db_default())
# mission_queued_behind() (migration 0005) takes the robot's queue lock (missions.rows.ROBOT_QUEUE_LOCK_SQL)
# shared, then looks at the queue with a snapshot of its own: the statement's is taken before anything in
# it runs, the lock included. The same statement records the write (WriteRecord): both are stored or neither.
MISSION_INSERT_SQL = f"""
    WITH new AS (
        INSERT INTO {Mission._meta.db_table} ({", ".join(mission_columns(MISSION_INSERT_FIELDS))})
        VALUES ({", ".join(["%s"] * len(MISSION_INSERT_FIELDS))})
        RETURNING name, robot, queue_position
    ), record AS (
        INSERT INTO {WriteRecord._meta.db_table} (at, actor, action, object_name, via)
        SELECT now(), %s, %s, name, %s FROM new
    )
    SELECT queue_position, mission_queued_behind(robot, queue_position) FROM new
"""


# A robot taking an order needs no step (`takes_order_only`), only this flag, which keeps beat's
# sweep from sending the order again. It holds the order at this update or a later one. Running missions
# that another transaction holds (a step, a service) are skipped, not waited for.
ACCEPT_ORDERS_SQL = f"""
    WITH taken AS (
        SELECT * FROM unnest(%s::varchar[], %s::text[], %s::bigint[]) AS t(robot, order_id, order_update_id)
    ), free AS (
        SELECT name FROM {Mission._meta.db_table}
        WHERE robot IN (SELECT robot FROM taken) AND state = '{MissionState.RUNNING}' AND NOT order_accepted
        FOR NO KEY UPDATE SKIP LOCKED
    )
    UPDATE {Mission._meta.db_table} AS m SET order_accepted = true, updated_at = %s
    FROM taken AS t
    WHERE m.name IN (SELECT name FROM free) AND m.robot = t.robot
      AND m."order"->>'orderId' = t.order_id AND (m."order"->>'orderUpdateId')::bigint <= t.order_update_id
"""


def mission_orders_accepted(*, orders: Mapping[str, tuple[str, int]]) -> None:
    """Mark accepted the running missions' orders that robots took: robot -> (orderId, orderUpdateId).

    One statement, whatever the number of robots, so that it holds the rows it locks only while it runs. A
    mission a step holds is skipped, not waited for: waiting, the flush held the rows it had locked, and
    the steps of those robots queued behind the step it waited for. A skipped acceptance costs nothing:
    the sweep resends an order only on a state that does not hold it. An order that is not the mission's
    current one (a later update is already out, or the order came from elsewhere) matches nothing.
    """
    robots = list(orders)
    with connection.cursor() as cursor:
        cursor.execute(
            ACCEPT_ORDERS_SQL,
            [
                robots,
                [orders[robot][0] for robot in robots],
                [orders[robot][1] for robot in robots],
                timezone.now(),
            ],
        )


# --- assignment: binding unbound missions to free capable robots (issue 41) -----------------------------

# Both lock only rows no one else holds (`_bind`).
LOCK_FREE_ROBOTS_SQL = f"""
    SELECT name FROM {Robot._meta.db_table}
    WHERE name = ANY(%s) AND online AND lifecycle = '{Lifecycle.ALIVE}'
    ORDER BY name FOR UPDATE SKIP LOCKED
"""
LOCK_UNBOUND_SQL = f"""
    SELECT name FROM {Mission._meta.db_table}
    WHERE name = ANY(%s) AND robot IS NULL AND state = '{MissionState.PENDING}'
      AND lifecycle = '{Lifecycle.ALIVE}'
    ORDER BY name FOR UPDATE SKIP LOCKED
"""


# Bind each mission of the pairs (name, robot) that is still unbound to its robot if that robot is still
# free, recording the binding (as `missions.rows.binding_record`). Parameters: updated_at and bound_at, then
# the missions and their robots. Its snapshot is taken after the caller's locks: a binding another
# transaction committed before the robot was locked is seen, and the robot is not bound twice. `robot IS
# NULL` again: a mission is never bound twice.
BIND_SQL = f"""
    UPDATE {Mission._meta.db_table} AS m
    SET robot = b.robot, waiting_reason = NULL, updated_at = %s,
        assignment = m.assignment || jsonb_build_array(
            jsonb_build_object('robot', b.robot, 'bound_at', %s::text, 'released_at', NULL, 'reason', NULL)
        )
    FROM unnest(%s::varchar[], %s::varchar[]) AS b(name, robot)
    WHERE m.name = b.name AND m.robot IS NULL AND m.state = '{MissionState.PENDING}'
      AND NOT {robot_busy_sql("b.robot")}
    RETURNING m.name, m.robot
"""
# A claim locks its robot's best choice that no other claim or run holds (robots falling free together take
# different missions), read as the step's record: the step binds it in the write that starts it. The
# robot's own queue is not looked at again: the step holds the robot's lock and has just read it empty.
# Parameters: the choices twice.
CLAIM_SQL = f"""
    SELECT {", ".join(mission_columns(MISSION_RECORD_FIELDS))} FROM {Mission._meta.db_table}
    WHERE name = ANY(%s) AND robot IS NULL AND state = '{MissionState.PENDING}'
      AND lifecycle = '{Lifecycle.ALIVE}'
    ORDER BY array_position(%s::varchar[], name) LIMIT 1 FOR UPDATE SKIP LOCKED
"""
# An unbound mission still queued at its deadline never starts, as one of a robot's queue (the step's
# rule, `dispatch.step`): no robot's step sees it, so assignment's run ends it.
DEADLINE_UNBOUND_SQL = f"""
    UPDATE {Mission._meta.db_table}
    SET state = '{MissionState.FAILED}', end_timestamp = %s, updated_at = %s, waiting_reason = NULL,
        failure_reason = %s, failure_category = '{FailureCategory.DEADLINE}',
        node_status = node_status || jsonb_build_object(
            '{ROOT}', jsonb_build_object('state', '{MissionState.FAILED}', 'error_msg', NULL)
        )
    WHERE robot IS NULL AND state = '{MissionState.PENDING}' AND deadline <= %s
"""
WAITING_REASONS_SQL = f"""
    UPDATE {Mission._meta.db_table} AS m SET waiting_reason = w.reason, updated_at = %s
    FROM unnest(%s::varchar[], %s::text[]) AS w(name, reason)
    WHERE m.name = w.name AND m.robot IS NULL AND m.state = '{MissionState.PENDING}'
      AND m.waiting_reason IS DISTINCT FROM w.reason
"""


@dataclass(frozen=True)
class AssignmentRun:
    bound: dict[str, str]  # the bindings made: mission -> robot
    hold: float | None = None  # a burst is arriving: run again in this many seconds (`burst_hold`)
    idle_robots: int | None = None  # free robots the run left without a mission; None: not known


def missions_assign(*, with_reasons: bool = True) -> AssignmentRun:
    """Bind the unbound queued missions to free capable robots (`dispatch.assignment.assign`), record why
    the others wait (`with_reasons`), and step the robots bound.

    Without `with_reasons` only the free robots are read, and the missions only if one is: a run that a
    robot freed or a new mission asked for costs little when every robot is busy, which in a busy fleet
    is most runs (the reasons need every robot; the caller refreshes them now and then). The read takes no
    locks; the binding (`_bind`) binds only a mission still unbound to a robot still free, so that whatever
    number of runs go at once, a mission is bound once and a robot gets one mission. A binding skipped for
    a lock or a race is tried again by the next run, asked for at once.
    """
    now = timezone.now()
    with connection.cursor() as cursor:
        if with_reasons:  # a robot deleted: rare, and its missions wait at most until the next such run
            cursor.execute(RELEASE_ORPHANS_SQL, [now, binding_time(now), ROBOT_DELETED])
        cursor.execute(DEADLINE_UNBOUND_SQL, [now, now, DEADLINE_PASSED, now])
    inputs = assignment_inputs(free_only=not with_reasons)
    free_robots = sum(robot.online and robot.idle and robot.battery_ok for robot in inputs.robots)
    if not inputs.missions:
        # Read only the free robots: every one of them is idle. Every robot, without missions: none read.
        return AssignmentRun({}, idle_robots=None if with_reasons else free_robots)
    hold = burst_hold(
        [mission.created for mission in inputs.missions],
        free_robots,
        now=now,
        quiet=timedelta(seconds=settings.ASSIGNMENT_QUIET_SECONDS),
        longest=timedelta(seconds=settings.ASSIGNMENT_HOLD_SECONDS),
    )
    if hold is not None:
        return AssignmentRun({}, hold=hold.total_seconds(), idle_robots=free_robots)
    result = assign(inputs.missions, inputs.robots)
    with transaction.atomic():
        bound = _bind(result.bindings, now)
        changed = {
            name: reason for name, reason in result.waiting.items() if inputs.waiting_reasons[name] != reason
        }
        if changed and with_reasons:
            with connection.cursor() as cursor:
                cursor.execute(WAITING_REASONS_SQL, [now, list(changed), list(changed.values())])
        if len(bound) < len(result.bindings):
            request_assignment()
    return AssignmentRun(bound, idle_robots=free_robots - len(bound))


def mission_claim(*, robot: str) -> MissionRecord | None:
    """The robot, just fallen free, chooses its next mission from the unbound ones at once, by assignment's
    rules for it alone (the oldest of the highest priority it can do, unless its own queue comes first);
    returns that mission as it is stored, still unbound and locked until the caller's transaction ends: the
    step that ended the robot's last mission, which binds and starts it in one write (one row version and
    one change-feed row for both; nothing else is asked to step the robot).

    In a busy fleet robots fall free one at a time while missions wait: the robot is then the only free
    one, and binding it in its own step spares a run, a step and a transaction (issue 41's steady state).
    Robots that fall free together take different missions (each its best one no other claim holds); one
    whose choices all went to others meanwhile reads the pool again, once (`CLAIM_TRIES`): a robot that
    claims nothing falls idle and asks for an assignment run, which reads every free robot and the whole
    pool. Missions younger than `ASSIGNMENT_QUIET_SECONDS` are left to the run, which may be holding them
    for a burst, and so is a robot that none of the `CLAIM_PAGE` first missions suits (the run reads them
    all).
    """
    for _ in range(CLAIM_TRIES):
        now = timezone.now()
        inputs = claim_inputs(
            robot=robot,
            created_before=now - timedelta(seconds=settings.ASSIGNMENT_QUIET_SECONDS),
            limit=CLAIM_PAGE,
        )
        if not inputs.missions:
            return None
        choices = choices_of(inputs.robots[0], inputs.missions)
        if not choices:
            return None
        with connection.cursor() as cursor:
            cursor.execute(CLAIM_SQL, [choices, choices])
            rows = cursor.fetchall()
        if rows:
            return mission_records(rows)[0]
    return None


def _bind(bindings: dict[str, str], now: datetime) -> dict[str, str]:
    """Bind what `bindings` asks (mission -> robot) where the robot and mission are still free and no other
    transaction holds them (SKIP LOCKED: runs never wait for each other, nor deadlock, nor wait for a step);
    the robots bound are stepped once this commits. Returns the bindings made."""
    if not bindings:
        return {}
    with connection.cursor() as cursor:
        cursor.execute(LOCK_FREE_ROBOTS_SQL, [sorted(set(bindings.values()))])
        robots = {name for (name,) in cursor.fetchall()}
        cursor.execute(LOCK_UNBOUND_SQL, [sorted(bindings)])
        missions = [name for (name,) in cursor.fetchall() if bindings[name] in robots]
        if not missions:
            return {}
        cursor.execute(BIND_SQL, [now, binding_time(now), missions, [bindings[name] for name in missions]])
        bound = dict(cursor.fetchall())
    if bound:
        request_steps(sorted(set(bound.values())))
    return bound
