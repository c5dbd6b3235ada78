"""Pure reading of a robot's ``state``: acceptance, progress, actions, errors, telemetry.

Follows the document's rules for a master: progress comes from ``lastNodeId``/``lastNodeSequenceId``
and removed node states (never from the position), actions are found by ``actionId`` (never by list
position), FATAL errors make a robot unavailable while WARNINGs do not, ``information`` drives no logic.
3.0 additions: instant and zone actions are reported apart from the order's (found by ``actionId`` all
the same), a CRITICAL error ends the current order but not the robot's availability, and a robot that an
operator INTERVENED on takes only ``cancelOrder``.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from vda5050.models import ActionState, ActionStatus, ActionType, Error, ErrorLevel, OperatingMode, State
from vda5050.orders import Pose

FINAL_ACTION_STATUSES = frozenset({ActionStatus.FINISHED, ActionStatus.FAILED})
# The master is not in control in these modes and must send neither orders nor instant actions.
MODES_WITHOUT_MASTER = frozenset(
    {OperatingMode.STARTUP, OperatingMode.MANUAL, OperatingMode.SERVICE, OperatingMode.TEACHIN}
)
# 3.0: someone intervened on the robot; fleet control may only cancel its order.
MODE_CANCEL_ONLY = OperatingMode.INTERVENED
# Modes in which the robot takes no new order.
MODES_WITHOUT_ORDERS = MODES_WITHOUT_MASTER | {MODE_CANCEL_ONLY}
# Errors after which the robot cannot go on with its current order (3.0 CRITICAL: it can take new ones).
ORDER_ENDING_LEVELS = frozenset({ErrorLevel.CRITICAL, ErrorLevel.FATAL})

# Reference keys are compared case-insensitively without underscores: vendors send "orderId",
# "order_id" or "OrderID" alike.
ORDER_ID_KEY = "orderid"
ORDER_UPDATE_ID_KEY = "orderupdateid"
NODE_ID_KEY = "nodeid"
EDGE_ID_KEY = "edgeid"
ACTION_ID_KEY = "actionid"


@dataclass(frozen=True)
class Telemetry:
    """What the fleet shows about a robot; None where the state does not say (optional fields)."""

    pose: Pose | None
    position_initialized: bool | None
    battery_charge: float
    charging: bool
    operating_mode: OperatingMode
    paused: bool | None
    driving: bool
    manufacturer: str
    serial_number: str


def order_accepted(state: State, order_id: str, order_update_id: int) -> bool:
    """The robot holds this order at this update or a later one."""
    return state.order_id == order_id and state.order_update_id >= order_update_id


def order_rejection(state: State, order_id: str, order_update_id: int) -> Error | None:
    """The error by which the robot rejected this order (update), if any.

    Any error type counts (validationError, orderError, orderUpdateError or a vendor's own), as long as
    it references the orderId and, if it names one, the same orderUpdateId.
    """
    if order_accepted(state, order_id, order_update_id):
        return None
    for error in state.errors:
        references = _references(error)
        update_ids = references.get(ORDER_UPDATE_ID_KEY)
        if order_id in references.get(ORDER_ID_KEY, ()) and (
            update_ids is None or str(order_update_id) in update_ids
        ):
            return error
    return None


def last_node_reached(state: State, order_id: str, sequence_id: int) -> bool:
    """The robot has reached the node with ``sequence_id`` of this order (and reports it so)."""
    return (
        state.order_id == order_id
        and state.last_node_sequence_id >= sequence_id
        and all(node.sequence_id > sequence_id for node in state.node_states)
    )


def decision_point(state: State) -> int:
    """The sequenceId of the last released node the robot holds still ahead, else of the node it last
    reached: where an order update of its order must start."""
    released = [node.sequence_id for node in state.node_states if node.released]
    return max(released) if released else state.last_node_sequence_id


def waits_at_decision_point(state: State) -> bool:
    """The robot has driven its order's base and holds only horizon ahead: it waits for the base to be
    extended, standing still by design."""
    return bool(state.node_states) and not any(node.released for node in state.node_states)


def action_status(state: State, action_id: str) -> ActionStatus | None:
    """Status of one action by id, wherever the robot reports it; None while it does not."""
    statuses = [a.action_status for a in all_action_states(state) if a.action_id == action_id]
    return statuses[-1] if statuses else None


def all_action_states(state: State) -> list[ActionState]:
    """Order, instant and zone actions: one list in 2.x, three in 3.0."""
    return [*state.action_states, *(state.instant_action_states or ()), *(state.zone_action_states or ())]


def errors_referencing(
    state: State,
    *,
    order_id: str | None = None,
    node_ids: Collection[str] = (),
    edge_ids: Collection[str] = (),
    action_ids: Collection[str] = (),
) -> list[Error]:
    """Errors whose references name the order or any of the given nodes, edges or actions."""
    wanted = {
        ORDER_ID_KEY: {order_id} if order_id is not None else set(),
        NODE_ID_KEY: set(node_ids),
        EDGE_ID_KEY: set(edge_ids),
        ACTION_ID_KEY: set(action_ids),
    }
    return [
        error
        for error in state.errors
        if any(values & wanted.get(key, set()) for key, values in _references(error).items())
    ]


def fatal_errors(state: State) -> list[Error]:
    """Errors that make the robot unavailable until someone intervenes."""
    return [error for error in state.errors if error.error_level == ErrorLevel.FATAL]


def order_ending_errors(state: State) -> list[Error]:
    """Errors after which the robot does not go on with its current order (FATAL, 3.0 CRITICAL)."""
    return [error for error in state.errors if error.error_level in ORDER_ENDING_LEVELS]


def warnings(state: State) -> list[Error]:
    """Errors the robot can still work with (3.0 URGENT too)."""
    return [error for error in state.errors if error.error_level in (ErrorLevel.WARNING, ErrorLevel.URGENT)]


def is_idle(state: State) -> bool:
    """No nodes or edges left and every action done; only then may a new orderId be sent."""
    return (
        not state.node_states
        and not state.edge_states
        and all(action.action_status in FINAL_ACTION_STATUSES for action in state.action_states)
    )


def may_receive_orders(state: State) -> bool:
    return state.operating_mode not in MODES_WITHOUT_ORDERS


def may_receive_instant_action(state: State, action_type: str) -> bool:
    if state.operating_mode == MODE_CANCEL_ONLY:
        return action_type == ActionType.CANCEL_ORDER
    return state.operating_mode not in MODES_WITHOUT_MASTER


def robot_telemetry(state: State) -> Telemetry:
    position = state.agv_position
    return Telemetry(
        pose=Pose(position.x, position.y, position.theta, position.map_id) if position else None,
        position_initialized=position.position_initialized if position else None,
        battery_charge=state.battery_state.battery_charge,
        charging=state.battery_state.charging,
        operating_mode=state.operating_mode,
        paused=state.paused,
        driving=state.driving,
        manufacturer=state.manufacturer,
        serial_number=state.serial_number,
    )


def _references(error: Error) -> dict[str, set[str]]:
    """Reference values by normalised key."""
    references: dict[str, set[str]] = {}
    for reference in error.error_references or ():
        key = reference.reference_key.replace("_", "").lower()
        references.setdefault(key, set()).add(reference.reference_value.strip())
    return references
