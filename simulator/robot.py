"""One simulated VDA 5050 robot as a pure state machine: messages and time in, messages out.

No I/O: the runner feeds received payloads and the clock (``now``, UNIX seconds) into ``receive`` and
``tick`` and publishes what they return, so tests drive a robot with a fake clock.

The robot is as strict as a real AGV (VDA 5050 2.x order acceptance): a malformed order, a new order
while busy or far from its first node, an outdated or unstitchable update are rejected with a WARNING
in ``errors`` that references the order; an exact duplicate is discarded silently. Order actions run
one at a time with the robot standing still. A FATAL error (a failed action, a simulated failure)
makes the robot abandon its order as ``cancelOrder`` would: it stops, drops the remaining nodes and
edges and fails the actions not done; the error stays until the next order is accepted.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import orjson

from simulator.actions import (
    DOWNLOAD_MAP_SECONDS,
    ActionPlan,
    ClearLoads,
    Effect,
    SetLoad,
    SetMap,
    UnusableAction,
    VendorAction,
    as_number,
    parameters_of,
    plan_order_action,
    require,
)
from simulator.config import DEFAULT_INTERFACE_NAME, RobotConfig, SimulationSettings, Stack
from simulator.factsheet import factsheet_content
from simulator.motion import Pose, Target, angle_difference, jump_to, normalize_angle, step_towards
from vda5050.codec import LEGACY_INSTANT_ACTIONS_KEY, encode, header_for, parse_instant_actions, parse_order
from vda5050.errors import ProtocolError
from vda5050.maps import MAP_DOWNLOAD_LINK, MAP_ID, MAP_VERSION, has_maps
from vda5050.models import (
    Action,
    ActionState,
    ActionStatus,
    ActionType,
    AgvClass,
    AgvPosition,
    BatteryState,
    ConnectionContent,
    ConnectionState,
    Content,
    Edge,
    EdgeState,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    Header,
    Load,
    Map,
    MapStatus,
    Node,
    NodeState,
    OperatingMode,
    Order,
    SafetyState,
    StateContent,
    Velocity,
    VisualizationContent,
)
from vda5050.orders import check_order_graph
from vda5050.state import FINAL_ACTION_STATUSES
from vda5050.topics import RobotAddress, Topic, major_version_of, topic_for
from vda5050.versions import INSTANT_ACTION_BLOCKING_3, MAJOR_3, major_of

# errorType values: the document's predefined ones, plus our own (vendor-specific) names.
VALIDATION_ERROR = "validationError"
ORDER_ERROR = "orderError"
ORDER_UPDATE_ERROR = "orderUpdateError"
NO_ORDER_TO_CANCEL = "noOrderToCancel"
ACTION_ERROR = "actionError"
# 2.1 names no error types for maps (vendor-specific); 3.0 does (ERROR_TYPES_3).
DUPLICATE_MAP = "duplicateMap"
UNKNOWN_MAP = "unknownMap"
SIMULATED_FAILURE = "simulatedFailure"
# 3.0 renamed the predefined ones (UPPER_SNAKE); a 3.0 robot reports those names.
ERROR_TYPES_3 = {
    VALIDATION_ERROR: "VALIDATION_FAILURE",
    ORDER_ERROR: "INVALID_ORDER_ACTION",
    ORDER_UPDATE_ERROR: "OUTDATED_ORDER_UPDATE",
    NO_ORDER_TO_CANCEL: "NO_ORDER_TO_CANCEL",
    DUPLICATE_MAP: "DUPLICATE_MAP",
    UNKNOWN_MAP: "UNKNOWN_MAP_ID",
}
# What vda-5050-lib 1.4.0 reports for instant actions without the 1.1 key (Stack.VDA_5050_LIB_1_4).
LIB_1_4_KEY_REJECTION = (
    "invalid instant actions: TypeError: Invalid VDA 5050 InstantActions"
    " at #/allOf/1/required, #/instantActions"
)
LIB_1_4_NO_ORDER = "instant action is not executable: no active order to be canceled"

ACTION_FAILURE = "Action failure"  # Isaac Mission Dispatch shows this description as the failure reason
FAILURE_PERIOD_REACHED = "Failure period reached"
FIRST_MAP_VERSION = "1"  # the version of the map a robot starts on (and of one it switches to)
STANDARD_AGV_CLASSES = frozenset(agv_class.value for agv_class in AgvClass)
PUBLISH_OPTIONS: dict[Topic, tuple[int, bool]] = {  # (QoS, retained) per the document
    Topic.STATE: (0, False),
    Topic.VISUALIZATION: (0, False),
    Topic.CONNECTION: (1, True),
    Topic.FACTSHEET: (0, True),
}


@dataclass(frozen=True)
class Outgoing:
    """One message to publish."""

    kind: Topic
    topic: str
    payload: bytes
    qos: int
    retain: bool


@dataclass
class ActionRecord:
    """An action the robot knows of: one entry of ``actionStates`` plus how it is running."""

    action: Action
    status: ActionStatus = ActionStatus.WAITING
    result: str | None = None
    plan: ActionPlan | None = None
    ends_at: float | None = None  # None while running: until an outside event (stopTeleop)
    instant: bool = False  # reported in 3.0's instantActionStates, not actionStates

    @property
    def done(self) -> bool:
        return self.status in FINAL_ACTION_STATUSES

    def to_state(self) -> ActionState:
        return ActionState(
            action_id=self.action.action_id,
            action_type=self.action.action_type,
            action_description=self.action.action_description,
            action_status=self.status,
            result_description=self.result,
        )


class Rejection(Exception):
    """An order (or instant-actions message) the robot refuses; becomes a WARNING in ``errors``."""

    def __init__(self, error_type: str, description: str) -> None:
        super().__init__(description)
        self.error_type = error_type
        self.description = description


class SimulatedRobot:
    def __init__(
        self,
        config: RobotConfig,
        settings: SimulationSettings,
        *,
        now: float,
        topic_address: RobotAddress | None = None,
    ) -> None:
        """``topic_address`` gives the topic levels (default ``uagv/v<major>/<manufacturer>/<serial>``)."""
        self.config = config
        self.settings = settings
        self.version = config.vda_version or settings.version
        self.is_3 = major_of(self.version) >= MAJOR_3
        self.has_maps = has_maps(self.version)
        # who the robot is in message headers (the interface name is not part of a header)
        self.address = RobotAddress(DEFAULT_INTERFACE_NAME, config.manufacturer, config.serial, self.version)
        self.topic_address = topic_address or self.address
        self._pose = Pose(config.x, config.y, normalize_angle(config.theta))
        self._map_id = config.map_id
        # The maps the robot has (2.1+): mapId -> {mapVersion: status}; it starts with its map enabled.
        self._maps: dict[str, dict[str, MapStatus]] = {config.map_id: {FIRST_MAP_VERSION: MapStatus.ENABLED}}
        self._downloads: list[tuple[ActionRecord, float]] = []  # (downloadMap, when it is done)
        self._velocity = (0.0, 0.0, 0.0)
        self._driving = False
        self._paused = False
        self._teleop = False
        self._loads: list[Load] = []
        self._errors: list[Error] = []
        # the order
        self._order_id = ""
        self._order_update_id = 0
        self._zone_set_id: str | None = None  # echoed as the document asks; zones are not simulated
        self._last_node_id = ""
        self._last_node_sequence_id = 0
        self._nodes: list[Node] = []  # still to traverse, base then horizon
        self._edges: list[Edge] = []
        self._actions: dict[str, ActionRecord] = {}  # actionStates, in arrival order
        self._queue: deque[str] = deque()  # actionIds to run here, one after another
        self._running: str | None = None
        self._entered_edge: int | None = None  # sequenceId of the edge whose actions were queued
        self._accepted_orders = 0
        # publishing
        self._header_ids: dict[Topic, int] = {}
        self._state_changed = True
        self._factsheet_requested = False
        self._state_due = now
        self._visualization_due = now

    # --- the runner's interface --------------------------------------------------------------------

    def topic(self, kind: Topic) -> str:
        return topic_for(self.topic_address, kind)

    def subscriptions(self) -> list[str]:
        return [self.topic(Topic.ORDER), self.topic(Topic.INSTANT_ACTIONS)]

    def last_will(self, now: float) -> Outgoing:
        """Registered with the broker at connect time, sent by it if the connection breaks."""
        return self._connection(ConnectionState.CONNECTIONBROKEN, now)

    def connected(self, now: float) -> list[Outgoing]:
        """ONLINE, then the factsheet (retained, so masters find it) and a state."""
        self._factsheet_requested = True
        self._state_changed = True
        return [self._connection(ConnectionState.ONLINE, now), *self._due_messages(now)]

    def going_offline(self, now: float) -> Outgoing:
        return self._connection(ConnectionState.OFFLINE, now)

    def receive(self, kind: Topic, payload: bytes, now: float) -> list[Outgoing]:
        if kind == Topic.ORDER:
            self._receive_order(payload)
        elif kind == Topic.INSTANT_ACTIONS:
            self._receive_instant_actions(payload, now)
        else:
            return []
        self._progress(now, may_move=self.settings.completes_instantly)
        return self._due_messages(now)

    def tick(self, now: float) -> list[Outgoing]:
        """One motion step and whatever is due: a state on any change or every state_period."""
        self.advance(now)
        return self._due_messages(now)

    def advance(self, now: float) -> None:
        """One motion step without publishing (while disconnected: the robot keeps working)."""
        self._progress(now, may_move=True)

    def state_content(self) -> StateContent:
        """What the next state message will say (without header)."""
        return StateContent(
            maps=(
                [
                    Map(map_id=map_id, map_version=version, map_status=status)
                    for map_id, versions in self._maps.items()
                    for version, status in versions.items()
                ]
                if self.has_maps
                else None
            ),
            order_id=self._order_id,
            order_update_id=self._order_update_id,
            zone_set_id=self._zone_set_id,
            last_node_id=self._last_node_id,
            last_node_sequence_id=self._last_node_sequence_id,
            driving=self._driving,
            paused=self._paused,
            new_base_request=self._new_base_request(),
            operating_mode=OperatingMode.AUTOMATIC,
            node_states=[
                NodeState(
                    node_id=node.node_id,
                    sequence_id=node.sequence_id,
                    node_description=node.node_description,
                    released=node.released,
                    node_position=node.node_position,
                )
                for node in self._nodes
            ],
            edge_states=[
                EdgeState(
                    edge_id=edge.edge_id,
                    sequence_id=edge.sequence_id,
                    edge_description=edge.edge_description,
                    released=edge.released,
                    trajectory=edge.trajectory,
                )
                for edge in self._edges
            ],
            agv_position=self._agv_position(),
            velocity=self._velocity_model(),
            loads=list(self._loads),
            action_states=[
                record.to_state() for record in self._actions.values() if not (self.is_3 and record.instant)
            ],
            instant_action_states=[record.to_state() for record in self._actions.values() if record.instant]
            if self.is_3
            else None,
            battery_state=BatteryState(battery_charge=self.config.battery, charging=False),
            errors=list(self._errors),
            information=[],
            safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
        )

    # --- orders ------------------------------------------------------------------------------------

    def _receive_order(self, payload: bytes) -> None:
        try:
            order = parse_order(payload)
        except ProtocolError as exc:
            self._add_rejection(VALIDATION_ERROR, str(exc), raw_references(Topic.ORDER, payload))
            return
        try:
            self._take_order(order)
        except Rejection as exc:
            self._add_rejection(exc.error_type, exc.description, order_references(order))

    def _take_order(self, order: Order) -> None:
        """The acceptance algorithm of VDA 5050 2.1 (Figure 8), strict wherever the document allows."""
        self._check_addressee(order)
        problems = check_order_graph(order)
        if not order.order_id:
            problems.insert(0, "orderId is empty")
        if problems:
            raise Rejection(VALIDATION_ERROR, "; ".join(problems))
        check_usable(order)
        self._check_maps(order)
        if order.order_id != self._order_id:
            self._start_order(order)
        elif order.order_update_id < self._order_update_id:
            raise Rejection(
                ORDER_UPDATE_ERROR,
                f"orderUpdateId {order.order_update_id} is lower than the current {self._order_update_id}",
            )
        elif order.order_update_id > self._order_update_id:
            self._update_order(order)
        # an equal orderUpdateId is a resend of what the robot already has: discarded silently

    def _start_order(self, order: Order) -> None:
        if self._busy():
            raise Rejection(
                ORDER_ERROR,
                f"busy: order {self._order_id!r} is not finished (node states left or actions not"
                " FINISHED/FAILED); cancel it first",
            )
        first = order.nodes[0]
        if first.sequence_id != 0:
            raise Rejection(VALIDATION_ERROR, f"a new order starts at sequenceId 0, not {first.sequence_id}")
        self._check_start_node(first)
        self._order_id = order.order_id
        self._order_update_id = order.order_update_id
        self._zone_set_id = order.zone_set_id
        self._errors.clear()
        self._nodes = list(order.nodes[1:])
        self._edges = list(order.edges)
        self._actions = {
            action.action_id: ActionRecord(action)
            for element in (*order.nodes, *order.edges)
            for action in element.actions
        }
        self._queue.clear()
        self._running = None
        self._entered_edge = None
        self._arrive(first)
        self._accepted_orders += 1
        failure_period = self.config.failure_period
        if failure_period and self._accepted_orders % failure_period == 0:
            self._fail_on_purpose()

    def _check_maps(self, order: Order) -> None:
        """A 2.1+ robot drives only on maps it has enabled (the master must see to that, 2.1 section 6.7)."""
        if not self.has_maps:
            return
        for node in order.nodes:
            map_id = node.node_position.map_id if node.node_position else None
            if map_id is not None and MapStatus.ENABLED not in self._maps.get(map_id, {}).values():
                raise Rejection(UNKNOWN_MAP, f"node {node.node_id!r} is on map {map_id!r}, not enabled")

    def _check_start_node(self, node: Node) -> None:
        """The first node must be trivially reachable: the robot stands on it or within its range."""
        position = node.node_position
        if position is None:
            if node.node_id != self._last_node_id:
                raise Rejection(
                    ORDER_ERROR,
                    f"first node {node.node_id!r} has no nodePosition and is not the last node"
                    f" {self._last_node_id!r}",
                )
            return
        if position.map_id != self._map_id:
            raise Rejection(
                ORDER_ERROR,
                f"first node {node.node_id!r} is on map {position.map_id!r}, robot on {self._map_id!r}",
            )
        target = target_of(node)
        if not target.within_xy(self._pose):
            distance = math.hypot(target.x - self._pose.x, target.y - self._pose.y)
            raise Rejection(
                ORDER_ERROR,
                f"first node {node.node_id!r} is out of range: {distance:.3f} m from the robot, allowed"
                f" {target.deviation_xy} m",
            )

    def _update_order(self, order: Order) -> None:
        """Stitch at the decision point: keep the base, replace the horizon, append the rest."""
        first = order.nodes[0]
        decision_point = self._decision_point()
        if (first.node_id, first.sequence_id) != decision_point:
            raise Rejection(
                ORDER_UPDATE_ERROR,
                f"update starts at node {first.node_id!r} (sequenceId {first.sequence_id}), not at the"
                f" decision point {decision_point[0]!r} (sequenceId {decision_point[1]})",
            )
        horizon = [element for element in (*self._nodes, *self._edges) if not element.released]
        horizon_action_ids = {action.action_id for element in horizon for action in element.actions}
        # the stitching node's content is the robot's already (2.x): its actions are not taken again
        new_actions = [action for element in (*order.nodes[1:], *order.edges) for action in element.actions]
        reused = [
            a.action_id for a in new_actions if a.action_id in self._actions.keys() - horizon_action_ids
        ]
        if reused:
            raise Rejection(VALIDATION_ERROR, f"actionIds already used in this order: {', '.join(reused)}")
        for action_id in horizon_action_ids:
            self._actions.pop(action_id, None)
        self._nodes = [node for node in self._nodes if node.released] + list(order.nodes[1:])
        self._edges = [edge for edge in self._edges if edge.released] + list(order.edges)
        self._actions.update((action.action_id, ActionRecord(action)) for action in new_actions)
        self._order_update_id = order.order_update_id
        self._zone_set_id = order.zone_set_id
        self._state_changed = True

    def _decision_point(self) -> tuple[str, int]:
        """Last released node still ahead, else the node last reached."""
        released = [node for node in self._nodes if node.released]
        if released:
            return released[-1].node_id, released[-1].sequence_id
        return self._last_node_id, self._last_node_sequence_id

    def _busy(self, besides: ActionRecord | None = None) -> bool:
        """Nodes or edges left, or an action (other than ``besides``) not FINISHED/FAILED."""
        return bool(self._nodes or self._edges) or any(
            not record.done for record in self._actions.values() if record is not besides
        )

    def _new_base_request(self) -> bool:
        """A horizon waits and at most the decision point is left of the base."""
        released_ahead = sum(node.released for node in self._nodes)
        return released_ahead <= 1 and any(not node.released for node in self._nodes)

    def _check_addressee(self, message: Header) -> None:
        if (message.manufacturer, message.serial_number) != (self.config.manufacturer, self.config.serial):
            raise Rejection(
                VALIDATION_ERROR,
                f"addressed to manufacturer {message.manufacturer!r} serialNumber {message.serial_number!r},"
                f" this robot is {self.config.manufacturer!r} {self.config.serial!r}",
            )
        try:
            major = major_version_of(message.version)
        except ProtocolError as exc:
            raise Rejection(VALIDATION_ERROR, str(exc)) from None
        if major != self.address.major_version:
            raise Rejection(VALIDATION_ERROR, f"version {message.version} is not {self.version}")

    def _fail_on_purpose(self) -> None:
        """``failure_period``: every Nth order fails (FATAL: abandoned) or only warns and goes on."""
        level = ErrorLevel.WARNING if self.settings.fail_as_warning else ErrorLevel.FATAL
        self._add_error(
            SIMULATED_FAILURE,
            FAILURE_PERIOD_REACHED,
            level,
            [("nodeId", self._last_node_id), ("orderId", self._order_id)],
        )
        if level == ErrorLevel.FATAL:
            self._drop_order(FAILURE_PERIOD_REACHED)

    # --- execution ---------------------------------------------------------------------------------

    def _progress(self, now: float, *, may_move: bool) -> None:
        """Run actions and drive until blocked: an action still running, paused, or (at most) one
        motion step done; instant mode goes on until the decision point."""
        instant = self.settings.completes_instantly
        self._finish_downloads(now)
        start = self._pose
        moved = False
        while True:
            if self._running is not None:
                record = self._actions[self._running]
                if record.ends_at is None or now < record.ends_at:
                    break
                self._running = None
                self._finish(record)
                continue
            if self._paused:
                break
            if self._queue:
                self._start(self._queue.popleft(), now)
                continue
            if not self._nodes or not self._nodes[0].released:
                break
            edge = self._edges[0] if self._edges else None
            if edge is not None and edge.sequence_id != self._entered_edge:
                self._entered_edge = edge.sequence_id
                self._queue.extend(action.action_id for action in edge.actions)
                continue
            target = target_of(self._nodes[0])
            if target.reached_by(self._pose):
                self._arrive(self._nodes.pop(0))
                continue
            if self._teleop or not may_move or (moved and not instant):
                break
            self._pose = (
                jump_to(self._pose, target) if instant else step_towards(self._pose, target, self._step(edge))
            )
            moved = True
        if may_move:  # a message between two ticks neither starts nor stops driving
            self._set_motion(start, driving=moved and not instant)

    def _arrive(self, node: Node) -> None:
        """Node traversed: drop it (and the edge before it) from the states, queue its actions."""
        self._last_node_id = node.node_id
        self._last_node_sequence_id = node.sequence_id
        self._edges = [edge for edge in self._edges if edge.sequence_id > node.sequence_id]
        self._queue.extend(action.action_id for action in node.actions)
        self._state_changed = True

    def _start(self, action_id: str, now: float) -> None:
        record = self._actions.get(action_id)
        if record is None or record.status != ActionStatus.WAITING:
            return
        self._state_changed = True
        try:
            plan = plan_order_action(record.action, self.settings.completes_instantly)
        except UnusableAction as exc:
            self._action_failed(record, str(exc))
            return
        record.plan = plan
        record.status = ActionStatus.RUNNING
        record.ends_at = None if plan.duration is None else now + plan.duration
        self._running = action_id

    def _finish(self, record: ActionRecord) -> None:
        plan = record.plan
        assert plan is not None  # only started actions run
        self._state_changed = True
        if plan.fails:
            self._action_failed(record, plan.result)
            return
        for effect in plan.effects:
            self._apply(effect)
        record.status = ActionStatus.FINISHED
        record.result = plan.result

    def _action_failed(self, record: ActionRecord, reason: str) -> None:
        record.status = ActionStatus.FAILED
        record.result = reason
        self._add_error(
            ACTION_ERROR,
            ACTION_FAILURE,
            ErrorLevel.FATAL,
            [("actionId", record.action.action_id), ("orderId", self._order_id)],
        )
        self._drop_order(ACTION_FAILURE)

    def _apply(self, effect: Effect) -> None:
        match effect:
            case SetMap(map_id=map_id):
                self._localize_on(map_id)
            case SetLoad(load_id=load_id, load_type=load_type):
                self._loads = [Load(load_id=load_id, load_type=load_type)]
            case ClearLoads():
                self._loads = []

    def _step(self, edge: Edge | None) -> float:
        if edge is not None and edge.max_speed is not None and 0 < edge.max_speed < self.settings.speed:
            return edge.max_speed * self.settings.tick_period
        return self.settings.step

    def _set_motion(self, start: Pose, *, driving: bool) -> None:
        """Velocity in the vehicle frame from this tick's step; a change of ``driving`` is an event."""
        if driving:
            period = self.settings.tick_period
            dx, dy = (self._pose.x - start.x) / period, (self._pose.y - start.y) / period
            cos, sin = math.cos(start.theta), math.sin(start.theta)
            omega = angle_difference(self._pose.theta, start.theta) / period
            self._velocity = (dx * cos + dy * sin, -dx * sin + dy * cos, omega)
        else:
            self._velocity = (0.0, 0.0, 0.0)
        if driving != self._driving:
            self._driving = driving
            self._state_changed = True

    def _stop(self) -> None:
        self._driving = False
        self._velocity = (0.0, 0.0, 0.0)
        self._state_changed = True

    # --- instant actions ---------------------------------------------------------------------------

    def _receive_instant_actions(self, payload: bytes, now: float) -> None:
        if self.config.stack == Stack.VDA_5050_LIB_1_4 and not _has_key(payload, LEGACY_INSTANT_ACTIONS_KEY):
            self._add_rejection(
                VALIDATION_ERROR, LIB_1_4_KEY_REJECTION, raw_references(Topic.INSTANT_ACTIONS, payload)
            )
            return
        try:
            message = parse_instant_actions(payload)
            self._check_addressee(message)
            if self.is_3:
                _check_instant_blocking(message.actions)
        except ProtocolError as exc:
            self._add_rejection(VALIDATION_ERROR, str(exc), raw_references(Topic.INSTANT_ACTIONS, payload))
            return
        except Rejection as exc:
            self._add_rejection(
                exc.error_type, exc.description, raw_references(Topic.INSTANT_ACTIONS, payload)
            )
            return
        self._state_changed = True  # every instant-actions message is answered with a state
        for action in message.actions:
            if action.action_id in self._actions:
                continue  # a resend: it ran already, the state reports how
            record = ActionRecord(action, instant=True)
            if self._refuses_cancel_silently(record):
                continue
            self._actions[action.action_id] = record
            self._run_instant(record, now)

    def _run_instant(self, record: ActionRecord, now: float) -> None:
        match record.action.action_type:
            case ActionType.CANCEL_ORDER:
                self._cancel_order(record)
            case ActionType.START_PAUSE:
                self._paused = True
                self._stop()
                finish(record, "paused")
            case ActionType.STOP_PAUSE:
                self._paused = False
                finish(record, "resumed")
            case ActionType.STATE_REQUEST:
                finish(record, "state sent")
            case ActionType.FACTSHEET_REQUEST:
                self._factsheet_requested = True
                finish(record, "factsheet sent")
            case ActionType.START_TELEOP:
                self._teleop = True
                self._stop()
                finish(record, "teleoperation started")
            case ActionType.STOP_TELEOP:
                self._teleop = False
                self._end_pause_order(now)
                finish(record, "teleoperation stopped")
            case ActionType.INIT_POSITION:
                self._init_position(record)
            case ActionType.DOWNLOAD_MAP | ActionType.ENABLE_MAP | ActionType.DELETE_MAP if self.has_maps:
                self._map_action(record, now)
            case _:
                self._instant_action_failed(
                    record, f"unsupported instant action type {record.action.action_type!r}"
                )

    def _refuses_cancel_silently(self, record: ActionRecord) -> bool:
        """vda-5050-lib 1.4.0: a cancelOrder without an order gets an error, and no action state."""
        if not (
            self.config.stack == Stack.VDA_5050_LIB_1_4
            and record.action.action_type == ActionType.CANCEL_ORDER
            and not self._busy()
        ):
            return False
        references = [("topic", Topic.INSTANT_ACTIONS.value), ("actionId", record.action.action_id)]
        self._add_error(
            NO_ORDER_TO_CANCEL,
            LIB_1_4_NO_ORDER,
            ErrorLevel.WARNING,
            [*references, ("actionType", "cancelOrder")],
        )
        return True

    def _cancel_order(self, record: ActionRecord) -> None:
        """Stop at once; unfinished actions FAILED, node/edge states emptied, orderId kept."""
        if not self._busy(besides=record):
            record.status = ActionStatus.FAILED
            record.result = "no order to cancel"
            self._add_error(
                NO_ORDER_TO_CANCEL,
                "There is no order to cancel",
                ErrorLevel.WARNING,
                [("actionId", record.action.action_id), ("orderId", self._order_id)],
            )
            return
        self._drop_order("cancelled", besides=record)
        finish(record, f"order {self._order_id} cancelled")

    def _drop_order(self, reason: str, besides: ActionRecord | None = None) -> None:
        """Stop at once: unfinished actions (but ``besides``) FAILED, node/edge states emptied."""
        for record in self._actions.values():
            if record is not besides and not record.done:
                record.status = ActionStatus.FAILED
                record.result = reason
        self._nodes = []
        self._edges = []
        self._queue.clear()
        self._running = None
        self._entered_edge = None
        self._stop()

    def _end_pause_order(self, now: float) -> None:
        record = self._actions.get(self._running) if self._running else None
        if record is not None and record.action.action_type == VendorAction.PAUSE_ORDER:
            record.ends_at = now

    def _init_position(self, record: ActionRecord) -> None:
        if self._busy(besides=record):
            self._instant_action_failed(record, "the robot is busy with an order")
            return
        parameters = parameters_of(record.action)
        try:
            x, y, theta = (as_number(require(parameters, key), key) for key in ("x", "y", "theta"))
            map_id = require(parameters, "mapId")
            if not all(math.isfinite(value) for value in (x, y, theta)) or not isinstance(map_id, str):
                raise UnusableAction("x, y, theta must be finite numbers and mapId a string")
        except UnusableAction as exc:
            self._instant_action_failed(record, str(exc))
            return
        self._pose = Pose(x, y, normalize_angle(theta))
        self._localize_on(map_id)
        if "lastNodeId" in parameters:
            self._last_node_id = str(parameters["lastNodeId"])
        finish(record, "position set")

    # --- maps (2.1+) -----------------------------------------------------------------------------------

    def _localize_on(self, map_id: str) -> None:
        """Switch to `map_id` (load_map, initPosition): a map the robot switches to is one it has, enabled."""
        self._map_id = map_id
        versions = self._maps.setdefault(map_id, {})
        if MapStatus.ENABLED not in versions.values():
            versions[max(versions, default=FIRST_MAP_VERSION)] = MapStatus.ENABLED
        self._state_changed = True

    def _map_action(self, record: ActionRecord, now: float) -> None:
        """downloadMap, enableMap, deleteMap, as 2.1 section 6.7 and its action table describe them."""
        parameters = parameters_of(record.action)
        try:
            map_id, version = (str(require(parameters, key)) for key in (MAP_ID, MAP_VERSION))
            if record.action.action_type == ActionType.DOWNLOAD_MAP:
                require(parameters, MAP_DOWNLOAD_LINK)
        except UnusableAction as exc:
            self._instant_action_failed(record, str(exc))
            return
        versions = self._maps.get(map_id, {})
        match record.action.action_type:
            case ActionType.DOWNLOAD_MAP:
                downloading = any(
                    parameters_of(d.action).get(MAP_ID) == map_id
                    and str(parameters_of(d.action).get(MAP_VERSION)) == version
                    for d, _ in self._downloads
                )
                if version in versions or downloading:
                    self._map_action_failed(record, DUPLICATE_MAP, f"map {map_id} {version} is already here")
                    return
                record.status = ActionStatus.RUNNING
                seconds = 0.0 if self.settings.completes_instantly else DOWNLOAD_MAP_SECONDS
                self._downloads.append((record, now + seconds))
                self._finish_downloads(now)
            case _ if version not in versions:
                self._map_action_failed(record, UNKNOWN_MAP, f"map {map_id} {version} is not here")
            case ActionType.ENABLE_MAP:
                self._maps[map_id] = {
                    v: MapStatus.ENABLED if v == version else MapStatus.DISABLED for v in versions
                }
                finish(record, f"map {map_id} {version} enabled")
            case ActionType.DELETE_MAP:
                del versions[version]
                if not versions:
                    del self._maps[map_id]
                finish(record, f"map {map_id} {version} deleted")

    def _finish_downloads(self, now: float) -> None:
        """Downloads whose time is up: the map is there, DISABLED, and the downloadMap FINISHED."""
        done = [(record, at) for record, at in self._downloads if at <= now]
        for record, _ in done:
            parameters = parameters_of(record.action)
            map_id, version = str(parameters[MAP_ID]), str(parameters[MAP_VERSION])
            self._maps.setdefault(map_id, {})[version] = MapStatus.DISABLED
            finish(record, f"map {map_id} {version} downloaded")
            self._state_changed = True
        self._downloads = [entry for entry in self._downloads if entry not in done]

    def _map_action_failed(self, record: ActionRecord, error_type: str, reason: str) -> None:
        record.status = ActionStatus.FAILED
        record.result = reason
        self._add_error(error_type, reason, ErrorLevel.WARNING, [("actionId", record.action.action_id)])

    def _instant_action_failed(self, record: ActionRecord, reason: str) -> None:
        record.status = ActionStatus.FAILED
        record.result = reason
        self._add_error(ACTION_ERROR, reason, ErrorLevel.WARNING, [("actionId", record.action.action_id)])

    # --- errors ------------------------------------------------------------------------------------

    def _add_rejection(self, error_type: str, description: str, references: list[tuple[str, str]]) -> None:
        self._add_error(error_type, description, ErrorLevel.WARNING, references)

    def _add_error(
        self, error_type: str, description: str, level: ErrorLevel, references: list[tuple[str, str]]
    ) -> None:
        """Append an error; one repeating an existing error (but for the headerId) replaces it, so a
        master resending a rejected order does not grow the list. A 3.0 robot names predefined types as
        3.0 does."""
        error = Error(
            error_type=ERROR_TYPES_3.get(error_type, error_type) if self.is_3 else error_type,
            error_description=description,
            error_level=level,
            error_references=[
                ErrorReference(reference_key=key, reference_value=value) for key, value in references
            ],
        )
        identity = error_identity(error)
        self._errors = [existing for existing in self._errors if error_identity(existing) != identity]
        self._errors.append(error)
        self._state_changed = True

    # --- outgoing messages -------------------------------------------------------------------------

    def _due_messages(self, now: float) -> list[Outgoing]:
        messages = []
        if self._factsheet_requested:
            self._factsheet_requested = False
            messages.append(self._factsheet(now))
        if self._state_changed or now >= self._state_due - self.settings.tick_period / 2:
            self._state_changed = False
            self._state_due = now + self.settings.state_period
            messages.append(self._message(Topic.STATE, self.state_content(), now))
        period = self.settings.visualization_period
        if period > 0 and now >= self._visualization_due - self.settings.tick_period / 2:
            self._visualization_due = now + period
            content = VisualizationContent(
                agv_position=self._agv_position(),
                velocity=self._velocity_model(),
                # 3.0: the state this position goes with (the last one sent)
                reference_state_header_id=max(self._header_ids.get(Topic.STATE, 0) - 1, 0)
                if self.is_3
                else None,
            )
            messages.append(self._message(Topic.VISUALIZATION, content, now))
        return messages

    def _connection(self, connection_state: ConnectionState, now: float) -> Outgoing:
        return self._message(Topic.CONNECTION, ConnectionContent(connection_state=connection_state), now)

    def _factsheet(self, now: float) -> Outgoing:
        message = self._message(
            Topic.FACTSHEET, factsheet_content(self.config, self.settings, self.version), now
        )
        agv_class = self.config.robot_type.value
        if agv_class in STANDARD_AGV_CLASSES or self.is_3:  # 3.0's mobileRobotClass is free text
            return message
        # Isaac's MANIPULATOR/HUMANOID are outside the 2.x enum; publish them as Isaac's robots do.
        body = orjson.loads(message.payload)
        body["typeSpecification"]["agvClass"] = agv_class
        return Outgoing(message.kind, message.topic, orjson.dumps(body), message.qos, message.retain)

    def _message(self, kind: Topic, content: Content, now: float) -> Outgoing:
        header_id = self._header_ids.get(kind, 0)
        self._header_ids[kind] = header_id + 1
        header = header_for(self.address, header_id=header_id, at=datetime.fromtimestamp(now, UTC))
        qos, retain = PUBLISH_OPTIONS[kind]
        return Outgoing(kind, self.topic(kind), encode(content, header), qos, retain)

    def _agv_position(self) -> AgvPosition:
        return AgvPosition(
            x=self._pose.x,
            y=self._pose.y,
            theta=self._pose.theta,
            map_id=self._map_id,
            position_initialized=True,
        )

    def _velocity_model(self) -> Velocity:
        vx, vy, omega = self._velocity
        return Velocity(vx=vx, vy=vy, omega=omega)


def target_of(node: Node) -> Target:
    position = node.node_position
    assert position is not None  # check_usable rejected orders with nodes we cannot locate
    return Target.of(
        position.x,
        position.y,
        position.theta,
        position.allowed_deviation_xy,
        position.allowed_deviation_theta,
    )


def check_usable(order: Order) -> None:
    """Fields the robot cannot follow make it reject the order instead of silently ignoring them."""
    for index, node in enumerate(order.nodes[1:], start=1):
        if node.node_position is None:
            raise Rejection(ORDER_ERROR, f"nodes[{index}] ({node.node_id!r}) has no nodePosition")
    for index, edge in enumerate(order.edges):
        for field_name in ("trajectory", "corridor"):
            if getattr(edge, field_name) is not None:
                raise Rejection(ORDER_ERROR, f"edges[{index}].{field_name} is not supported")


def finish(record: ActionRecord, result: str) -> None:
    record.status = ActionStatus.FINISHED
    record.result = result


def order_references(order: Order) -> list[tuple[str, str]]:
    return [
        ("headerId", str(order.header_id)),
        ("topic", Topic.ORDER.value),
        ("orderId", order.order_id),
        ("orderUpdateId", str(order.order_update_id)),
    ]


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


def raw_references(kind: Topic, payload: bytes) -> list[tuple[str, str]]:
    """References of a message that did not parse: whatever of them the raw JSON has."""
    try:
        data: Any = orjson.loads(payload)
    except orjson.JSONDecodeError:
        data = None
    references = [("topic", kind.value)]
    if isinstance(data, dict):
        keys = ("headerId", "orderId", "orderUpdateId") if kind == Topic.ORDER else ("headerId",)
        references += [(key, str(data[key])) for key in keys if key in data]
    return references


def error_identity(error: Error) -> tuple[Any, ...]:
    references = tuple(
        (reference.reference_key, reference.reference_value)
        for reference in error.error_references or ()
        if reference.reference_key != "headerId"
    )
    return error.error_type, error.error_description, error.error_level, references
