"""What a robot's state holds, judged without a step: the digest the bridge compares to tell which states
need a step, and whether the robot took, lacks or finished its mission's order (bridge, beat, step)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

import orjson

from vda5050 import state as vda_state
from vda5050.models import ActionStatus, State

FINAL = vda_state.FINAL_ACTION_STATUSES  # an instant action in one of these is no longer tracked
STARTED = frozenset({ActionStatus.INITIALIZING, ActionStatus.RUNNING, ActionStatus.PAUSED})
# A robot's state that arrived this long after its order was sent would hold the order had the robot got
# it; an earlier one may have left the robot before the order reached it, so it says nothing.
ORDER_ECHO = timedelta(seconds=1)


@dataclass(frozen=True)
class StateDigest:
    """What steps read in a robot's state, for the bridge to tell which states need a step.

    `full` changes with anything a step reads. `events` and `finished_actions` with what needs a step
    whatever order the robot holds: started actions, errors, operating mode, charging, battery in whole
    percent, pause, maps, zone sets; and the actions that finished or failed, apart because a robot taking an
    order commonly drops the finished ones of the order before and of its instant actions from its state,
    which tells a step nothing (`takes_order_only`). Pose and other high-rate fields are left out of all
    three on purpose: a moving robot must not cost a step per state message. Battery counts in whole percent
    because it gates queued missions at the critical level.
    """

    full: str
    events: str
    finished_actions: str  # a JSON array of "actionId=STATUS"; NO_FINISHED_ACTIONS when not known
    order_id: str
    order_update_id: int
    busy: bool  # nodes, edges or actions of an order left to do (not vda5050.state.is_idle)


def state_digest(state: State) -> StateDigest:
    actions = vda_state.all_action_states(state)  # 3.0 reports instant actions apart
    progress = [
        state.order_id,
        str(state.order_update_id),
        state.last_node_id,
        str(state.last_node_sequence_id),
        ",".join(str(node.sequence_id) for node in state.node_states),
        str(len(state.edge_states)),
        ",".join(f"{a.action_id}={a.action_status.value}" for a in actions if a.action_status not in FINAL),
    ]
    finished_actions = orjson.dumps(
        sorted(f"{a.action_id}={a.action_status.value}" for a in actions if a.action_status in FINAL)
    ).decode()
    events = [
        # Started: a state that takes an order whose action is already under way (a pause_order the robot
        # starts where it stands) needs its step, which puts the robot in TELEOP.
        ",".join(a.action_id for a in actions if a.action_status in STARTED),
        ",".join(
            f"{e.error_type}/{e.error_level.value}/"
            + "+".join(f"{r.reference_key}:{r.reference_value}" for r in e.error_references or ())
            for e in state.errors
        ),
        state.operating_mode.value,
        str(state.battery_state.charging),
        str(int(state.battery_state.battery_charge)),
        str(state.paused),
        # A map enabled (or gone) starts or holds a mission that names it.
        ",".join(f"{m.map_id}/{m.map_version}/{m.map_status.value}" for m in state.maps or ()),
        # A zone set arrived, enabled or gone: the next move of its distribution (`dispatch.zone_sets`).
        ",".join(f"{z.zone_set_id}/{z.zone_set_status.value}" for z in state.zone_sets or ()),
    ]
    return StateDigest(
        full="|".join([*progress, finished_actions, *events]),
        events="|".join(events),
        finished_actions=finished_actions,
        order_id=state.order_id,
        order_update_id=state.order_update_id,
        busy=not vda_state.is_idle(state),
    )


# --- Orders: taken, lacked, finished ---------------------------------------------------------------------
# Every judgement of whether a robot took, lacks or finished its mission's order, wherever it is made: the
# step itself (`_follow_order`, `_resend_due`); the bridge (`takes_order_only`: the state needs no step, the
# flush marks the order accepted, `missions.services.mission_orders_accepted`); beat (`order_lacked`: the
# resend sweep, `order_finished`: the stalled-mission check, both read in `missions.selectors`).


@dataclass(frozen=True)
class HeldOrder:
    """The order a robot's latest state holds, whether it is still busy with it, and when that state
    arrived (None if not recorded)."""

    order_id: str
    order_update_id: int
    busy: bool
    arrived_at: datetime | None


def arrived_after_order(state_arrived_at: datetime | None, order_sent_at: datetime) -> bool:
    """A state that arrived then would hold the order sent at `order_sent_at`, had the robot got it."""
    return state_arrived_at is not None and state_arrived_at >= order_sent_at + ORDER_ECHO


def order_lacked(
    held: HeldOrder | None, *, order_id: str | None, update_id: int | None, sent_at: datetime
) -> bool:
    """The robot's latest state arrived after the order had time to reach it, and is on another order or
    on an older update of this one: its step will send the order again (`_resend_due`). A robot that took
    the order but whose state has not been stepped yet, or whose state is still on its way, lacks nothing:
    a step would find nothing to do, and under load only turn a backlog into more load."""
    if held is None or not arrived_after_order(held.arrived_at, sent_at):
        return False
    return held.order_id != order_id or update_id is None or held.order_update_id < update_id


def order_finished(held: HeldOrder | None, *, order_id: str, update_id: int) -> bool:
    """The robot is idle at the end of this order (or a later update of it)."""
    return (
        held is not None and not held.busy and held.order_id == order_id and held.order_update_id >= update_id
    )


# A digest stored by a bridge of a version that did not record finished actions apart.
NO_FINISHED_ACTIONS = ""


def _no_action_finished(before: str, after: str) -> bool:
    """No action finished or failed between the two states: every one that did in `after` had in `before`
    (those that are gone no longer matter)."""
    if after == before:
        return True
    if before == NO_FINISHED_ACTIONS:
        return False
    return set(orjson.loads(after)) <= set(orjson.loads(before))


def takes_order_only(before: StateDigest, after: StateDigest) -> bool:
    """The robot took a new order, or a newer update of the order it runs, and nothing else a step reads
    changed: the step that sent the order did all there is to do, so this state needs none.

    Whether the order is one of ours and the update the latest is for the bridge's acceptance write to
    check (`missions.services.mission_orders_accepted`). Leaving one order unfinished for another is not
    taking an order only: the step must see the first one end. Nor is taking an update of the order the
    robot had stopped at the end of: the route that update carries (one sent ahead that reached the robot
    late) starts running now, and its step must see that. The finished actions of the order before and of
    instant actions, which a robot taking an order commonly drops from its state, do not count: the state
    that showed each one finish asked for its step already.
    """
    if not after.busy or after.events != before.events:
        return False
    if not _no_action_finished(before.finished_actions, after.finished_actions):
        return False
    if before.busy:
        return after.order_id == before.order_id and after.order_update_id > before.order_update_id
    return after.order_id != before.order_id
