"""Instant actions on a simulated robot: receiving them, and carrying each one out at once.

Every instant-actions message is answered with a state; an actionId the robot knows already is a
resend and runs no second time. ``Stack.VDA_5050_LIB_1_4`` mimics npm vda-5050-lib 1.4.0's AGV.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import orjson

from simulator.acceptance import check_addressee
from simulator.actions import ActionRun, UnusableAction, VendorAction, as_number, parameters_of, require
from simulator.battery import Battery
from simulator.config import RobotConfig, Stack
from simulator.errors import (
    ACTION_ERROR,
    NO_ORDER_TO_CANCEL,
    VALIDATION_ERROR,
    ErrorReport,
    Rejection,
    raw_references,
)
from simulator.maps import RobotMaps
from simulator.motion import Drive, VehiclePose, normalize_angle
from simulator.orders import CurrentOrder
from simulator.outbox import Outbox
from simulator.zones import RobotZones
from vda5050.codec import LEGACY_INSTANT_ACTIONS_KEY, parse_instant_actions
from vda5050.errors import ProtocolError
from vda5050.models import Action, ActionType
from vda5050.topics import RobotAddress, Topic
from vda5050.versions import INSTANT_ACTION_BLOCKING_3

# What vda-5050-lib 1.4.0 reports for instant actions without the 1.1 key (Stack.VDA_5050_LIB_1_4).
LIB_1_4_KEY_REJECTION = (
    "invalid instant actions: TypeError: Invalid VDA 5050 InstantActions"
    " at #/allOf/1/required, #/instantActions"
)
LIB_1_4_NO_ORDER = "instant action is not executable: no active order to be canceled"
# The instant actions that switch how the robot works (``_switch``), and what each reports when done.
SWITCH_RESULTS = {
    ActionType.START_PAUSE: "paused",
    ActionType.STOP_PAUSE: "resumed",
    ActionType.STATE_REQUEST: "state sent",
    ActionType.FACTSHEET_REQUEST: "factsheet sent",
    ActionType.START_TELEOP: "teleoperation started",
    ActionType.STOP_TELEOP: "teleoperation stopped",
}


@dataclass(eq=False)
class InstantActionHandler:
    """Checks each instant-actions message and carries out its actions."""

    config: RobotConfig
    address: RobotAddress
    is_3: bool
    has_maps: bool
    order: CurrentOrder
    maps: RobotMaps
    zones: RobotZones
    drive: Drive
    errors: ErrorReport
    outbox: Outbox
    battery: Battery

    def receive(self, payload: bytes, now: float) -> None:
        if self.config.stack == Stack.VDA_5050_LIB_1_4 and not _has_key(payload, LEGACY_INSTANT_ACTIONS_KEY):
            self.errors.warn(
                VALIDATION_ERROR, LIB_1_4_KEY_REJECTION, raw_references(Topic.INSTANT_ACTIONS, payload)
            )
            return
        try:
            message = parse_instant_actions(payload)
            check_addressee(message, self.config, self.address)
            if self.is_3:
                _check_instant_blocking(message.actions)
        except ProtocolError as exc:
            self.errors.warn(VALIDATION_ERROR, str(exc), raw_references(Topic.INSTANT_ACTIONS, payload))
            return
        except Rejection as exc:
            self.errors.warn(exc.error_type, exc.description, raw_references(Topic.INSTANT_ACTIONS, payload))
            return
        self.outbox.state_changed = True  # every instant-actions message is answered with a state
        runs = self.order.runs
        for action in message.actions:
            if action.action_id in runs:
                continue  # a resend: it ran already, the state reports how
            run = ActionRun(action, instant=True)
            if self._refuses_cancel_silently(run):
                continue
            runs[action.action_id] = run
            self._run(run, now)

    def _run(self, run: ActionRun, now: float) -> None:
        match run.action.action_type:
            case ActionType.CANCEL_ORDER:
                self._cancel_order(run)
            case ActionType.INIT_POSITION:
                self._init_position(run)
            case ActionType.DOWNLOAD_MAP | ActionType.ENABLE_MAP | ActionType.DELETE_MAP if self.has_maps:
                self.maps.act(run, now)
            case ActionType.ENABLE_ZONE_SET | ActionType.DELETE_ZONE_SET if self.is_3:
                self.zones.act(run)
            case ActionType.START_CHARGING if self.battery.can_charge:
                self.battery.start_charging(now)
                run.finish("charging" if self.battery.charging else "full")
            case ActionType.STOP_CHARGING if self.battery.can_charge:
                self.battery.stop_charging(now)
                run.finish("charging stopped")
            case action_type if action_type in SWITCH_RESULTS:
                self._switch(action_type, now)
                run.finish(SWITCH_RESULTS[action_type])
            case action_type:
                self.errors.refuse_action(
                    run, ACTION_ERROR, f"unsupported instant action type {action_type!r}"
                )

    def _switch(self, action_type: str, now: float) -> None:
        """An instant action that switches how the robot works; it cannot fail."""
        drive = self.drive
        match action_type:
            case ActionType.START_PAUSE:
                drive.paused = True
                drive.stop()
            case ActionType.STOP_PAUSE:
                drive.paused = False
            case ActionType.FACTSHEET_REQUEST:
                self.outbox.factsheet_requested = True
            case ActionType.START_TELEOP:
                drive.teleop = True
                drive.stop()
            case ActionType.STOP_TELEOP:
                drive.teleop = False
                self._end_pause_order(now)
        # stateRequest needs nothing: every instant-actions message is answered with a state

    def _refuses_cancel_silently(self, run: ActionRun) -> bool:
        """vda-5050-lib 1.4.0: a cancelOrder without an order gets an error, and no action state."""
        if not (
            self.config.stack == Stack.VDA_5050_LIB_1_4
            and run.action.action_type == ActionType.CANCEL_ORDER
            and not self.order.busy()
        ):
            return False
        references = [("topic", Topic.INSTANT_ACTIONS.value), ("actionId", run.action.action_id)]
        self.errors.warn(NO_ORDER_TO_CANCEL, LIB_1_4_NO_ORDER, [*references, ("actionType", "cancelOrder")])
        return True

    def _cancel_order(self, run: ActionRun) -> None:
        """Stop at once; unfinished actions FAILED, node/edge states emptied, orderId kept."""
        order = self.order
        if not order.busy(besides=run):
            run.fail("no order to cancel")
            self.errors.warn(
                NO_ORDER_TO_CANCEL,
                "There is no order to cancel",
                [("actionId", run.action.action_id), ("orderId", order.order_id)],
            )
            return
        order.drop("cancelled", besides=run)
        self.drive.stop()
        run.finish(f"order {order.order_id} cancelled")

    def _end_pause_order(self, now: float) -> None:
        order = self.order
        run = order.runs.get(order.running) if order.running else None
        if run is not None and run.action.action_type == VendorAction.PAUSE_ORDER:
            run.ends_at = now

    def _init_position(self, run: ActionRun) -> None:
        if self.order.busy(besides=run):
            self.errors.refuse_action(run, ACTION_ERROR, "the robot is busy with an order")
            return
        parameters = parameters_of(run.action)
        try:
            x, y, theta = (as_number(require(parameters, key), key) for key in ("x", "y", "theta"))
            map_id = require(parameters, "mapId")
            if not all(math.isfinite(value) for value in (x, y, theta)) or not isinstance(map_id, str):
                raise UnusableAction("x, y, theta must be finite numbers and mapId a string")
        except UnusableAction as exc:
            self.errors.refuse_action(run, ACTION_ERROR, str(exc))
            return
        self.drive.pose = VehiclePose(x, y, normalize_angle(theta))
        self.maps.localize_on(map_id)
        if "lastNodeId" in parameters:
            self.order.last_node_id = str(parameters["lastNodeId"])
        run.finish("position set")


def _has_key(payload: bytes, key: str) -> bool:
    try:
        data: Any = orjson.loads(payload)
    except orjson.JSONDecodeError:
        return False
    return isinstance(data, dict) and key in data


def _check_instant_blocking(actions: list[Action]) -> None:
    """3.0: instant actions are NONE-blocking."""
    for index, action in enumerate(actions):
        if action.blocking_type != INSTANT_ACTION_BLOCKING_3:
            raise Rejection(VALIDATION_ERROR, f"actions[{index}].blockingType must be NONE in VDA 5050 3.0")
