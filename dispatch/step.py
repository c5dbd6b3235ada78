"""One dispatch step for one robot: pure decisions, no I/O.

Given what is stored (the robot, its current or next mission, its unfinished instant actions) and the
robot's latest VDA 5050 state, `step` returns what to store and which messages to send. The caller
(`missions.robot_step.robot_step`) holds the robot's row lock, so steps of one robot never interleave; a
step only reads the latest state, so a duplicate or late wake-up just finds nothing to do.

No Django, paho or Redis imports: states, kinds, categories and lifecycles are the vocabulary's
(``dispatch.vocabulary``), which compare equal to the API's plain strings.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime, timedelta

from dispatch import engine, faults
from dispatch.ending import DEADLINE_PASSED, TIMED_OUT, end, finish
from dispatch.held import FINAL, arrived_after_order
from dispatch.instant import (
    cancel_of_order,
    describe,
    order_cancel,
    pending_action,
    send_instant_actions,
    switch_to_legacy_key,
    track_charging,
    track_instant_actions,
)
from dispatch.records import ActionRecord, DispatchSettings, MissionRecord, Outgoing, RobotView, StepResult
from dispatch.sent import SentOrder, build_order, order_update_for, sent_order, stored
from dispatch.start import maps_missing_for, release_unaccepted, try_start
from dispatch.vocabulary import (
    FailureCategory,
    Lifecycle,
    MissionState,
    NodeKind,
    RobotState,
)
from dispatch.zones import answerable
from vda5050 import compat, orders
from vda5050 import state as vda_state
from vda5050.models import (
    ActionStatus,
    ActionType,
    Error,
    OrderContent,
    Response,
    ResponsesContent,
    State,
)

PAUSE_ORDER = "pause_order"  # the reference's action that hands the robot to teleoperation
ORDER_KINDS = frozenset({NodeKind.ROUTE, NodeKind.MOVE, NodeKind.ACTION})

ACTION_FAILURE = "Action failure"
NO_POSITION = "Robot does not report its position"
ZONE_WAITING = "Waiting for zone"  # a running route's waiting reason at a zone's edge: "Waiting for zone Z"


def step(
    *,
    now: datetime,
    robot: RobotView,
    state: State | None,
    state_arrived_at: datetime | None,
    mission: MissionRecord | None,
    actions: list[ActionRecord],
    settings: DispatchSettings,
) -> StepResult:
    """Advance `robot` and its `mission` (the RUNNING one, else the head of its queue) by one step.

    `state_arrived_at` is when `state` reached the server (None if not known)."""
    result = StepResult(
        robot_state=robot.state,
        mission=mission,
        actions=[replace(a) for a in actions],
        switch_teleop=robot.switch_teleop,
    )
    track_instant_actions(result, state, state_arrived_at)
    switch_to_legacy_key(result, robot, state)
    track_charging(result, state)
    before = mission
    if mission is not None:
        mission = replace(mission)
        result.mission = mission
        if mission.state == MissionState.PENDING:
            try_start(result, robot, state, mission, now)
        if mission.state == MissionState.RUNNING and not release_unaccepted(result, robot, state, mission):
            _advance(result, robot, state, state_arrived_at, mission, now, settings)
        track_charging(result, state)  # a mission that ended at startCharging leaves its robot charging
    send_instant_actions(result, robot, state, now, settings)
    if robot.zone_reach is not None:
        _zone_news(result, robot, state, before)
    return result


# --- zones (`dispatch.zones`: the zone plan decides, the step carries it out) -----------------------------


def _zone_news(
    result: StepResult, robot: RobotView, state: State | None, before: MissionRecord | None
) -> None:
    """Answer the robot's 3.0 zone requests as the plan last decided, and ask for a plan run when what the
    plan reads of the robot changed: a new order, progress on it, its mission's end, or requests the plan
    has not answered (or answers to requests the robot no longer makes)."""
    reach = robot.zone_reach
    assert reach is not None
    if reach.responses_due and reach.responses and robot.online:
        answers = [Response(request_id=request, grant_type=grant) for request, grant in reach.responses]
        result.messages.append(Outgoing(ResponsesContent(responses=answers)))
    after = result.mission
    if before is not None and after is not None:
        progress = (after.progress or {}).get("lastNodeSequenceId")
        moved = progress != (before.progress or {}).get("lastNodeSequenceId")
        if moved or _order_id(after) != _order_id(before) or after.done:
            result.zones_plan = True
    if (
        robot.online and state is not None and state.zone_requests is not None
    ):  # the plan answers online robots
        asked = {request.request_id for request in state.zone_requests if answerable(request)}
        if asked != {request for request, _ in reach.responses}:
            result.zones_plan = True


def _order_id(mission: MissionRecord) -> str | None:
    return mission.order["orderId"] if mission.order is not None else None


def _within_reach(robot: RobotView, order: OrderContent) -> OrderContent:
    """A route's new order as far as zones let it reach: of an order the plan has not seen, nothing but
    its start (the plan, asked for by the step, releases the rest leg by leg)."""
    if robot.zone_reach is None:
        return order
    return orders.hold_back(order, robot.zone_reach.through(order.order_id))


def _reach_further(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    mission: MissionRecord,
    leaf: engine.Node,
    now: datetime,
) -> None:
    """Extend the running route's base through what the zone plan now allows (all of it once no zones
    are to be minded), as an order update of the order the robot holds: the robot drives on from its
    decision point, or sets off again from it if it waited there. The mission says which zones it waits
    for meanwhile. Only once the robot holds the order as last sent: an update must start at the decision
    point the robot has."""
    if mission.order is None or leaf.kind != NodeKind.ROUTE:
        return
    if robot.zone_reach is None and all(node["released"] for node in mission.order["nodes"]):
        return  # no zones, nothing held back: the hot path parses no order here
    sent = sent_order(mission.order)
    if sent.leaf != leaf.index or sent.ahead is not None:
        return
    order = sent.stored
    last = order.nodes[-1].sequence_id
    through = last if robot.zone_reach is None else min(robot.zone_reach.through(order.order_id), last)
    waiting = robot.zone_reach.waiting if robot.zone_reach is not None and through < last else ()
    if waiting:
        mission.waiting_reason = f"{ZONE_WAITING} {', '.join(waiting)}"
    elif mission.waiting_reason is not None and mission.waiting_reason.startswith(ZONE_WAITING):
        mission.waiting_reason = None
    if (
        through <= orders.last_base_node(order).sequence_id
        or not mission.order_accepted
        or not _may_update(result, robot, state, mission)
    ):
        return
    update = orders.release_update(order, through)
    mission.order = stored(orders.stitch(order, update))
    mission.order_sent_at = now
    mission.order_accepted = False
    result.messages.append(Outgoing(update))


# --- advancing a running mission ----------------------------------------------------------------------


def _advance(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    state_arrived_at: datetime | None,
    mission: MissionRecord,
    now: datetime,
    settings: DispatchSettings,
) -> None:
    try:
        tree = engine.apply_route_updates(engine.parse_tree(mission.mission_tree), mission.update_nodes)
    except engine.TreeError as exc:
        end(result, mission, MissionState.FAILED, now, reason=str(exc), category=FailureCategory.ROBOT_APP)
        return
    if _ended_by_time_or_owner(result, robot, state, mission, tree, now):
        return
    if mission.order is not None and state is not None:
        _follow_order(result, robot, state, state_arrived_at, mission, tree, now, settings)
        if mission.done:
            return
    if mission.needs_canceled:
        _cancel(result, state, mission, tree, now)
        if mission.done or mission.needs_canceled:
            return
    _tick(result, robot, state, state_arrived_at, mission, tree, now, settings)


def _ended_by_time_or_owner(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    mission: MissionRecord,
    tree: engine.Tree,
    now: datetime,
) -> bool:
    """Timeout, deadline and robot deletion end a mission at once and stop the robot."""
    assert mission.start_timestamp is not None
    if robot.lifecycle == Lifecycle.PENDING_DELETE:
        reason, category = f"Robot {robot.name} was deleted", FailureCategory.ROBOT_APP
        result.delete_robot = True
    elif now - mission.start_timestamp >= timedelta(seconds=mission.timeout):
        reason, category = TIMED_OUT, FailureCategory.TIMEOUT
    elif mission.deadline is not None and now >= mission.deadline:
        reason, category = DEADLINE_PASSED, FailureCategory.DEADLINE
    else:
        return False
    if _order_active(state, mission) and not result.delete_robot:
        cancel_of_order(result, mission)
    finish(result, mission, tree, MissionState.FAILED, now, reason=reason, category=category)
    return True


def _order_active(state: State | None, mission: MissionRecord) -> bool:
    """The mission's order (with the order update sent ahead, if any) may still be executing on the robot."""
    if mission.order is None:
        return False
    if (
        state is None
        or state.order_id != mission.order["orderId"]
        or state.order_update_id < mission.order["orderUpdateId"]
    ):
        return True  # not known to be taken, it may still arrive
    return not vda_state.is_idle(state)


# --- the mission's order, and the order update sent ahead (`dispatch.sent`) ------------------------------


def _follow_order(
    result: StepResult,
    robot: RobotView,
    state: State,
    state_arrived_at: datetime | None,
    mission: MissionRecord,
    tree: engine.Tree,
    now: datetime,
    settings: DispatchSettings,
) -> None:
    """Acceptance, resend, rejection, progress and errors of the running leaf's order, and acceptance,
    resend and rejection of the order update sent ahead with the next leaf. A robot that refuses the update,
    or lacks the order it extends, has it dropped (`_drop_ahead`): the next leaf gets an order of its own.
    A robot that lost the order, or stalled on it, is taken over (`dispatch.faults`, `_take_over`)."""
    sent = sent_order(mission.order)
    leaf = tree.nodes[sent.leaf]
    if mission.node_status[leaf.name]["state"] != MissionState.RUNNING:
        mission.progress_seen_at = None  # no stall clock while no leaf runs on the order
        return
    if faults.order_ended(mission, sent) or faults.order_lost(robot, state, state_arrived_at, mission, sent):
        _take_over(result, robot, state, mission, leaf, sent, now, settings)
        return
    if not mission.order_accepted:
        order_id = sent.stored.order_id
        rejection = vda_state.order_rejection(state, order_id, sent.message.order_update_id)
        if rejection is not None:
            result.rejected = True
            _leaf_failed(mission, leaf, describe([rejection]))
            return
        if sent.ahead is not None and vda_state.order_rejection(state, order_id, sent.ahead.order_update_id):
            result.rejected = True
            sent = _drop_ahead(mission, sent, state)
        leaf_order_held = vda_state.order_accepted(state, order_id, sent.message.order_update_id)
        if vda_state.order_accepted(state, order_id, sent.latest.order_update_id):
            mission.order_accepted = True
        elif _resend_due(result, state, state_arrived_at, mission, tree, leaf, now, settings):
            if sent.ahead is not None and not leaf_order_held:
                # No robot takes an update of an order it lacks: both again, in order. Not the order alone
                # with the update dropped: the first sending may still reach the robot (a broker that was
                # away delivers it late), and a robot holding the update would then drive the next route
                # twice. One that has both takes neither again (an equal orderUpdateId is a resend, a lower
                # one an orderUpdateError about that id only, which `order_rejection` does not count).
                result.messages.append(Outgoing(sent.message))
            mission.order_sent_at = now
            result.messages.append(Outgoing(_resent(sent, state)))
        if not leaf_order_held:
            return
    failures = _fatal_errors_for(state, sent.stored)
    if failures:
        _leaf_failed(mission, leaf, describe(failures))
        if not vda_state.is_idle(state):
            cancel_of_order(result, mission)  # a robot that keeps a failed order must not block the next
        return
    if leaf.kind == NodeKind.ACTION:
        _follow_action(result, state, mission, leaf, sent.message)
    else:
        _follow_route(state, mission, leaf, sent)
    if (
        mission.node_status[leaf.name]["state"] == MissionState.RUNNING
        and not mission.needs_canceled
        and pending_action(result, ActionType.CANCEL_ORDER) is None
        and faults.watch_progress(robot, state, mission, now, settings.order_stall.total_seconds())
    ):
        _end_stalled(result, state, mission, now, settings)


def _may_update(result: StepResult, robot: RobotView, state: State | None, mission: MissionRecord) -> bool:
    """An order update may go out now: the mission is not being canceled, no cancelOrder is pending (3.0:
    no order update after cancelOrder), and the robot is online and may take orders."""
    return (
        not mission.needs_canceled
        and state is not None
        and robot.online
        and vda_state.may_receive_orders(state)
        and pending_action(result, ActionType.CANCEL_ORDER) is None
    )


def _resent(sent: SentOrder, state: State) -> OrderContent:
    """The latest message again. A robot that holds an earlier update of the running leaf's own order (its
    base extended, `_reach_further`) gets that update as it was sent, from the decision point it has."""
    latest = sent.latest
    if (
        sent.ahead is None
        and latest.order_update_id > 0
        and state.order_id == latest.order_id
        and state.order_update_id < latest.order_update_id
    ):
        return orders.unstitch(latest, vda_state.decision_point(state))[1]
    return latest


def _end_stalled(
    result: StepResult, state: State, mission: MissionRecord, now: datetime, settings: DispatchSettings
) -> None:
    """An order the robot took and does not execute is canceled; once the robot confirms, the rest goes out
    anew (`_take_over`). A robot that stalled on an order update (a route sent ahead) gets the compatibility
    rule ORDER_UPDATE_NOT_EXECUTED: it is sent no routes ahead from then on."""
    faults.end_stalled(mission, now)
    cancel_of_order(result, mission)
    if state.order_update_id > 0:
        seconds = settings.order_stall.total_seconds()
        why = faults.stalled_reason(state.order_id, state.order_update_id, seconds)
        result.rules_applied.append((compat.Rule.ORDER_UPDATE_NOT_EXECUTED, why))


def _take_over(
    result: StepResult,
    robot: RobotView,
    state: State,
    mission: MissionRecord,
    leaf: engine.Node,
    sent: SentOrder,
    now: datetime,
    settings: DispatchSettings,
) -> None:
    """The robot no longer runs the leaf's order: it lost it (`faults.order_lost`), or its stalled order
    was canceled (`faults.order_ended`) and the robot confirmed. An action or move fails (the robot may or
    may not have done it: the tree decides what follows); a route goes on with a new order of the
    waypoints the robot had not reached, from where it stands, once it can take one. The update sent ahead
    is dropped: the next leaf gets an order of its own."""
    if faults.order_ended(mission, sent):
        cancel = order_cancel(result, mission)
        seconds = settings.order_stall.total_seconds()
        update_id = mission.progress["orderUpdateId"]
        if cancel is not None and cancel.status not in FINAL:
            if faults.cancel_overdue(mission, now, seconds):  # the stall clock's wake-up, or a state's
                mission.progress_seen_at = None
                reason = faults.unconfirmed_reason(sent.latest.order_id, update_id, seconds)
                _leaf_failed(mission, leaf, reason)
            return
        reason = faults.stalled_reason(sent.latest.order_id, update_id, seconds)
    else:
        reason = faults.lost_reason(sent.stored.order_id)
    mission.progress_seen_at = None  # no stall clock: the robot's own states wake the steps until then
    if leaf.kind != NodeKind.ROUTE:
        _leaf_failed(mission, leaf, reason)
        return
    if sent.ahead is not None:
        sent = _drop_ahead(mission, sent, state)
    if (
        not robot.online
        or not vda_state.is_idle(state)
        or not vda_state.may_receive_orders(state)
        or pending_action(result, ActionType.CANCEL_ORDER) is not None
    ):
        return  # the rest waits until the robot can take it
    waypoints = faults.remaining_waypoints(sent.message, mission.progress)
    if not waypoints:
        mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.COMPLETED)
        return
    pose = vda_state.robot_telemetry(state).pose
    if pose is None:
        _leaf_failed(mission, leaf, NO_POSITION)
        return
    assert leaf.index is not None
    order = orders.route_order(
        mission=mission.name,
        node_index=leaf.index,
        attempt=mission.attempts.get(leaf.name, 0),
        start=pose,
        waypoints=waypoints,
        start_deviation_xy=settings.start_deviation_xy,
    )
    _send_order(result, mission, leaf, _within_reach(robot, order), now)


def _send_order(
    result: StepResult, mission: MissionRecord, leaf: engine.Node, order: OrderContent, now: datetime
) -> None:
    """Send the order that runs `leaf` (a new orderId: the leaf's next attempt)."""
    mission.attempts = {**mission.attempts, leaf.name: mission.attempts.get(leaf.name, 0) + 1}
    mission.order = stored(order)
    mission.order_sent_at = now
    mission.order_accepted = False
    mission.progress = None
    mission.progress_seen_at = None
    mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.RUNNING)
    result.messages.append(Outgoing(order))


def _drop_ahead(mission: MissionRecord, sent: SentOrder, state: State | None) -> SentOrder:
    """Forget the order update sent ahead: the order is the running leaf's alone again. The next leaf gets
    an order of its own when it starts; having been sent once (`attempts`), it is never sent ahead again."""
    mission.order = stored(sent.message)
    mission.order_accepted = state is not None and vda_state.order_accepted(
        state, sent.message.order_id, sent.message.order_update_id
    )
    return SentOrder(sent.message, sent.leaf, sent.message)


def _resend_due(
    result: StepResult,
    state: State,
    state_arrived_at: datetime | None,
    mission: MissionRecord,
    tree: engine.Tree,
    leaf: engine.Node,
    now: datetime,
    settings: DispatchSettings,
) -> bool:
    """An unacknowledged order is re-sent after a while, once a state that arrived well after it shows the
    robot lacks it, unless the robot may not take orders now or the order went stale with a route update
    (then it is canceled, never re-sent), or is being canceled (3.0: no order update after cancelOrder). A
    state that may have left the robot before the order reached it (a bridge behind on a busy fleet stores
    such states late) is no reason to resend: that would only add load when there is too much."""
    if mission.order_sent_at is not None:
        if now - mission.order_sent_at < settings.order_resend:
            return False
        if not arrived_after_order(state_arrived_at, mission.order_sent_at):
            return False
    if mission.needs_canceled or pending_action(result, ActionType.CANCEL_ORDER) is not None:
        return False
    return vda_state.may_receive_orders(state) and not _route_update_pending(tree, mission, leaf, settings)


def _follow_action(
    result: StepResult, state: State, mission: MissionRecord, leaf: engine.Node, order: OrderContent
) -> None:
    action = order.nodes[0].actions[0]
    status = vda_state.action_status(state, action.action_id)
    if status == ActionStatus.FINISHED:
        mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.COMPLETED)
        if action.action_type == PAUSE_ORDER and result.robot_state == RobotState.TELEOP:
            result.robot_state = RobotState.ON_TASK
    elif status == ActionStatus.FAILED:
        errors = vda_state.errors_referencing(state, action_ids=[action.action_id])
        _leaf_failed(mission, leaf, describe(errors) if errors else ACTION_FAILURE)
        if action.action_type == PAUSE_ORDER and result.robot_state == RobotState.TELEOP:
            result.robot_state = RobotState.ON_TASK
    elif action.action_type == PAUSE_ORDER and status is not None:
        result.robot_state = RobotState.TELEOP


def _follow_route(state: State, mission: MissionRecord, leaf: engine.Node, sent: SentOrder) -> None:
    """A route or move is done once the robot has passed its last node: stopped there with nothing left to
    do, or driving on into the order update sent ahead."""
    order = sent.message
    last = order.nodes[-1]
    waypoints = order.nodes[1:]
    reached = [
        node for node in waypoints if vda_state.last_node_reached(state, order.order_id, node.sequence_id)
    ]
    if leaf.kind == NodeKind.ROUTE:
        exact = sum(
            1 for node in reached if node.node_position and not node.node_position.allowed_deviation_xy
        )
        if mission.task_status.get(leaf.name) != exact:
            mission.task_status = {**mission.task_status, leaf.name: exact}
    if vda_state.last_node_reached(state, order.order_id, last.sequence_id) and (
        vda_state.is_idle(state) or _ahead_held(state, sent)
    ):
        mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.COMPLETED)


def _stopped_on(state: State, order: OrderContent) -> bool:
    """The robot holds `order` and has nothing left to do: it stopped at its end."""
    return vda_state.order_accepted(state, order.order_id, order.order_update_id) and vda_state.is_idle(state)


def _ahead_held(state: State, sent: SentOrder) -> bool:
    """The robot holds the order update sent ahead."""
    return sent.ahead is not None and vda_state.order_accepted(
        state, sent.ahead.order_id, sent.ahead.order_update_id
    )


def _fatal_errors_for(state: State, order: OrderContent) -> list[Error]:
    """Errors that end the order (FATAL, 3.0 CRITICAL) about this order, or about nothing in particular
    (the robot cannot go on)."""
    ids = _element_ids(order)
    referencing = vda_state.errors_referencing(
        state,
        order_id=order.order_id,
        node_ids=ids["nodes"],
        edge_ids=ids["edges"],
        action_ids=ids["actions"],
    )
    return [
        error
        for error in state.errors
        if error.error_level in vda_state.ORDER_ENDING_LEVELS
        and (error in referencing or not error.error_references)
    ]


def _element_ids(order: OrderContent) -> dict[str, list[str]]:
    return {
        "nodes": [node.node_id for node in order.nodes],
        "edges": [edge.edge_id for edge in order.edges],
        "actions": [action.action_id for node in order.nodes for action in node.actions],
    }


def _leaf_failed(mission: MissionRecord, leaf: engine.Node, message: str) -> None:
    mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.FAILED, message)
    mission.failure_reason = message


def _cancel(
    result: StepResult, state: State | None, mission: MissionRecord, tree: engine.Tree, now: datetime
) -> None:
    """A canceled running mission ends CANCELED once the robot has stopped its order (or had none)."""
    if not _order_active(state, mission) or _current_leaf_kind(tree, mission) not in ORDER_KINDS:
        finish(result, mission, tree, MissionState.CANCELED, now, category=FailureCategory.CANCELED)
        return
    if cancel_of_order(result, mission).status in FINAL:
        finish(result, mission, tree, MissionState.CANCELED, now, category=FailureCategory.CANCELED)


def _current_leaf_kind(tree: engine.Tree, mission: MissionRecord) -> str | None:
    leaf = engine.tick(tree, mission.node_status).current_leaf
    return leaf.kind if leaf is not None else None


def _tick(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    state_arrived_at: datetime | None,
    mission: MissionRecord,
    tree: engine.Tree,
    now: datetime,
    settings: DispatchSettings,
) -> None:
    tick = engine.tick(tree, mission.node_status)
    mission.node_status = tick.node_status
    if tick.current_node is not None:
        mission.current_node = tick.current_node
    if tick.mission_state != MissionState.RUNNING:
        end(
            result,
            mission,
            tick.mission_state,
            now,
            category=FailureCategory.ROBOT_APP if tick.mission_state == MissionState.FAILED else None,
        )
        return
    leaf = tick.current_leaf
    assert leaf is not None
    if (
        tick.leaf_to_start is not None
        and mission.order is not None
        and sent_order(mission.order).next_leaf == leaf.index
        and _take_up_ahead(result, robot, state, state_arrived_at, mission, tree, leaf, now, settings)
    ):
        return
    if _route_update_pending(tree, mission, leaf, settings):
        if _restart_updated_leaf(result, state, mission, leaf):
            # send the new order right away
            _tick(result, robot, state, state_arrived_at, mission, tree, now, settings)
        return
    if tick.leaf_to_start is None:
        _reach_further(result, robot, state, mission, leaf, now)
        _extend(result, robot, state, mission, tree, leaf, now)
        return
    if leaf.kind == NodeKind.NOTIFY:
        mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.RUNNING)
        result.notify = leaf.name
        return
    if (
        state is None
        or not robot.online
        or not vda_state.is_idle(state)
        or not vda_state.may_receive_orders(state)
    ):
        return  # the order waits until the robot can take it
    if pending_action(result, ActionType.CANCEL_ORDER) is not None:
        return
    if leaf.kind == NodeKind.ROUTE:
        # A map disabled or deleted since the mission started, or named by a route update: the leaf waits.
        mission.waiting_reason = maps_missing_for(state, [leaf])
        if mission.waiting_reason is not None:
            return
    pose = vda_state.robot_telemetry(state).pose
    if pose is None:
        _leaf_failed(mission, leaf, NO_POSITION)
        _tick(result, robot, state, state_arrived_at, mission, tree, now, settings)
        return
    attempt = mission.attempts.get(leaf.name, 0)
    order = build_order(mission.name, leaf, attempt, pose, settings.start_deviation_xy)
    if leaf.kind == NodeKind.ROUTE:
        order = _within_reach(robot, order)
    _send_order(result, mission, leaf, order, now)
    _extend(result, robot, state, mission, tree, leaf, now)


def _take_up_ahead(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    state_arrived_at: datetime | None,
    mission: MissionRecord,
    tree: engine.Tree,
    leaf: engine.Node,
    now: datetime,
    settings: DispatchSettings,
) -> bool:
    """`leaf`, now to start, was sent ahead (`_extend`). Once the robot holds that order update, the leaf
    runs on it with no order of its own, and the step goes on with it (True). If the robot refused it, or
    no longer holds the order it extends, it is dropped and the leaf gets an order of its own, as any
    other (False). Until then the leaf waits (True), and a robot stopped at the end of the running leaf
    without the update gets it again, identical, as any unacknowledged order: a state without it proves
    nothing by its timing alone (a robot or a machine starved for a second answers late), and an order of
    the leaf's own beside an update the robot may hold would drive the route twice or be refused as busy."""
    assert mission.order is not None
    sent = sent_order(mission.order)
    assert sent.ahead is not None
    if state is None:
        return True
    if _ahead_held(state, sent):
        mission.order = stored(sent.ahead)
        mission.order_accepted = True
        mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.RUNNING)
        if not _route_update_pending(tree, mission, leaf, settings):  # else it starts over (`_tick`)
            started = replace(mission)
            _follow_order(result, robot, state, state_arrived_at, mission, tree, now, settings)
            if mission.node_status[leaf.name]["state"] != MissionState.RUNNING:
                result.passed.append(started)
        if not mission.done:
            _tick(result, robot, state, state_arrived_at, mission, tree, now, settings)
        return True
    refused = vda_state.order_rejection(state, sent.ahead.order_id, sent.ahead.order_update_id) is not None
    if refused or state.order_id != sent.ahead.order_id:
        result.rejected = result.rejected or refused
        _drop_ahead(mission, sent, state)
        return False
    if _resend_due(result, state, state_arrived_at, mission, tree, leaf, now, settings):
        mission.order_sent_at = now
        result.messages.append(Outgoing(sent.ahead))
    return True


def _extend(
    result: StepResult,
    robot: RobotView,
    state: State | None,
    mission: MissionRecord,
    tree: engine.Tree,
    leaf: engine.Node,
    now: datetime,
) -> None:
    """Send the next leaf ahead, as an order update of the running route's order, when it is certain to
    follow, so that the robot drives on from the route's last node instead of stopping there for an order
    of its own. Its node state still changes when the running route is done (`_take_up_ahead`).

    The rule, conservative (README, "Routes without stops"):
    - the running leaf `leaf` is a route whose order went to the robot, which has not finished it;
    - the leaf that starts once `leaf` succeeds (`engine.next_leaf`) is a route, with waypoints on maps the
      robot has enabled, never sent before: nothing between the two can fail or branch (only composites
      and constants lie between them, whose outcomes the stored states fix), and a leaf sent ahead once
      that did not run on it gets an order of its own, never a second update;
    - no zones are to be minded (`RobotView.zone_reach`: the next leaf's route gets its own order, which
      the zone plan then releases leg by leg),
    - nothing is sent ahead already (one leaf ahead at most), no route update waits for `leaf` (checked
      before), the mission is not being canceled and no cancelOrder is pending (3.0: no order update after
      cancelOrder), and the robot is online and may take orders.
    Whatever else ends `leaf` first (its failure, cancel, timeout, deadline, a route update, the robot
    deleted) stops the order with cancelOrder, the update sent ahead with it.
    """
    if (
        leaf.kind != NodeKind.ROUTE
        or not robot.routes_ahead
        or robot.zone_reach is not None  # the zone plan has not seen the next leaf's route
        or mission.order is None
        or not _may_update(result, robot, state, mission)
    ):
        return
    sent = sent_order(mission.order)
    if sent.leaf != leaf.index or sent.ahead is not None or _stopped_on(state, sent.message):
        return
    following = engine.next_leaf(tree, mission.node_status, leaf.name)
    if (
        following is None
        or following.kind != NodeKind.ROUTE
        or not following.params["waypoints"]
        or following.name in mission.attempts
        or maps_missing_for(state, [following]) is not None
    ):
        return
    update = order_update_for(mission.name, sent.stored, following, attempt=0)
    mission.attempts = {**mission.attempts, following.name: 1}
    mission.order = stored(orders.stitch(sent.stored, update))
    mission.order_sent_at = now
    mission.order_accepted = False
    result.messages.append(Outgoing(update))


def _route_update_pending(
    tree: engine.Tree, mission: MissionRecord, leaf: engine.Node, settings: DispatchSettings
) -> bool:
    """The running route's order (or the order update that brought it) was built from waypoints that an
    update has since replaced. An order of the route's last waypoints alone (the rest resumed after the
    robot lost the order, `_take_over`) is stale only if they are not the route's last ones now."""
    if leaf.kind != NodeKind.ROUTE or mission.order is None or not mission.update_nodes:
        return False
    if (
        leaf.name not in mission.update_nodes
        or mission.node_status[leaf.name]["state"] != MissionState.RUNNING
    ):
        return False
    sent = sent_order(mission.order).message
    key = orders.order_key(sent.nodes[-1].node_id)
    assert key is not None
    if sent.order_update_id > 0:  # brought by an order update, from the decision point it started at
        before = sent.model_copy(
            update={"order_update_id": sent.order_update_id - 1, "nodes": sent.nodes[:1], "edges": []}
        )
        return order_update_for(mission.name, before, leaf, key.attempt) != sent
    first = sent.nodes[0].node_position
    assert first is not None
    start = orders.Pose(first.x, first.y, first.theta or 0.0, first.map_id)
    deviation = first.allowed_deviation_xy or 0.0
    if build_order(mission.name, leaf, key.attempt, start, deviation) == sent:
        return False
    return build_order(mission.name, leaf, key.attempt, start, deviation, tail=len(sent.nodes) - 1) != sent


def _restart_updated_leaf(
    result: StepResult, state: State | None, mission: MissionRecord, leaf: engine.Node
) -> bool:
    """Stop the stale order; once stopped, the leaf starts over with the new waypoints (a new order).

    True once the leaf is PENDING again, ready to start."""
    if _order_active(state, mission) and cancel_of_order(result, mission).status not in FINAL:
        return False
    mission.node_status = engine.set_leaf_state(mission.node_status, leaf.name, MissionState.PENDING)
    mission.order = None
    mission.order_accepted = False
    return True
