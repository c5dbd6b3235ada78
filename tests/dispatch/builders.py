"""Builders for dispatch-step tests: robot states, mission records, and a driver that plays a robot's side.

Every step run through `checked_step` has each message it emits encoded and validated against the
official VDA 5050 schemas, so no test can pass with a message a real robot would refuse.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from typing import Any

import orjson

from dispatch import engine
from dispatch.held import FINAL
from dispatch.records import ActionRecord, DispatchSettings, MissionRecord, RobotView, StepResult
from dispatch.step import step
from dispatch.vocabulary import Lifecycle, MissionState, RobotState
from tests.vda5050.schemas import VERSIONS, validate_message
from vda5050.codec import encode, header_for, utc_timestamp
from vda5050.models import (
    Action,
    ActionState,
    ActionStatus,
    ActionType,
    AgvPosition,
    BatteryState,
    EdgeState,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    InstantActionsContent,
    NodeState,
    OperatingMode,
    OrderContent,
    SafetyState,
    State,
    Velocity,
)
from vda5050.topics import RobotAddress

NOW = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
ROBOT = "carter01"
MISSION = "m1"
SETTINGS = DispatchSettings(
    order_resend=timedelta(seconds=3), instant_action_resend=timedelta(seconds=5), start_deviation_xy=0.5
)
POSE = (1.0, 2.0, 0.5, "map")

# --- mission trees in the API's stored shape -----------------------------------------------------------


def route(name: str, *points: tuple[float, float], parent: str = engine.ROOT, **pose: Any) -> dict[str, Any]:
    """A route through `points` (default one waypoint); `pose` adds fields to every waypoint."""
    waypoints = [{"x": x, "y": y, "theta": 0.0, "map_id": "map", **pose} for x, y in points or [(5.0, 6.0)]]
    return {"name": name, "parent": parent, "route": {"waypoints": waypoints}}


def move(name: str, *, distance: float = 1.0, parent: str = engine.ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "move": {"distance": distance}}


def action(
    name: str, action_type: str = "dummy_action", parent: str = engine.ROOT, **parameters: Any
) -> dict[str, Any]:
    return {
        "name": name,
        "parent": parent,
        "action": {"action_type": action_type, "action_parameters": parameters},
    }


def notify(name: str, parent: str = engine.ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "notify": {"url": "http://hooks.invalid/", "json_data": {}}}


def selector(name: str, parent: str = engine.ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "selector": {}}


def sequence(name: str, parent: str = engine.ROOT) -> dict[str, Any]:
    return {"name": name, "parent": parent, "sequence": {}}


def mission(*tree: dict[str, Any], **fields: Any) -> MissionRecord:
    """A queued mission of `tree` (default: one route `r`), as mission_create stores it."""
    mission_tree = list(tree) or [route("r")]
    defaults: dict[str, Any] = {
        "name": MISSION,
        "mission_tree": mission_tree,
        "timeout": 300.0,
        "deadline": None,
        "needs_canceled": False,
        "update_nodes": None,
        "lifecycle": Lifecycle.ALIVE,
        "state": MissionState.PENDING,
        "current_node": 0,
        "node_status": engine.initial_node_status(engine.parse_tree(mission_tree)),
        "task_status": {},
        "start_timestamp": None,
        "end_timestamp": None,
        "failure_reason": None,
        "failure_category": None,
        "waiting_reason": None,
        "order": None,
        "order_sent_at": None,
        "order_accepted": False,
        "attempts": {},
    }
    return MissionRecord(**(defaults | fields))


def robot_view(**fields: Any) -> RobotView:
    defaults: dict[str, Any] = {
        "name": ROBOT,
        "lifecycle": Lifecycle.ALIVE,
        "state": RobotState.IDLE,
        "online": True,
        "battery_critical_level": 10.0,
    }
    return RobotView(**(defaults | fields))


def instant_action(
    action_type: str,
    action_id: str | None = None,
    *,
    status: str | None = None,
    sent_at: datetime | None = None,
) -> ActionRecord:
    return ActionRecord(
        action_id=action_id or f"{ROBOT}-{action_type}-1",
        action_type=action_type,
        mission=None,
        status=status,
        sent_at=sent_at,
        send_count=int(sent_at is not None),
    )


# --- robot states --------------------------------------------------------------------------------------


def error(
    error_type: str, level: ErrorLevel = ErrorLevel.FATAL, description: str | None = None, **references: str
) -> Error:
    return Error(
        error_type=error_type,
        error_level=level,
        error_description=description,
        error_references=[ErrorReference(reference_key=k, reference_value=v) for k, v in references.items()]
        or None,
    )


def robot_state(
    *,
    order_id: str = "",
    order_update_id: int = 0,
    last_node_sequence_id: int = 0,
    node_states: Iterable[int] = (),
    action_states: Iterable[tuple[str, ActionStatus] | tuple[str, ActionStatus, str]] = (),
    errors: Iterable[Error] = (),
    battery: float = 80.0,
    charging: bool = False,
    operating_mode: OperatingMode = OperatingMode.AUTOMATIC,
    pose: tuple[float, float, float, str] | None = POSE,
    velocity: tuple[float, float, float] | None = None,
    header_id: int = 1,
    driving: bool = False,
) -> State:
    """A robot's state: `node_states` are the sequenceIds still to go (their edges are derived),
    `action_states` are (actionId, status[, actionType])."""
    remaining = sorted(node_states)
    edges = sorted({seq - 1 for seq in remaining if seq > last_node_sequence_id})
    return State(
        header_id=header_id,
        timestamp=utc_timestamp(NOW),
        version="2.0.0",
        manufacturer="RobotCompany",
        serial_number=ROBOT,
        order_id=order_id,
        order_update_id=order_update_id,
        last_node_id=f"{order_id}-s{last_node_sequence_id}" if order_id else "",
        last_node_sequence_id=last_node_sequence_id,
        driving=driving,
        operating_mode=operating_mode,
        node_states=[
            NodeState(node_id=f"{order_id}-s{seq}", sequence_id=seq, released=True) for seq in remaining
        ],
        edge_states=[
            EdgeState(edge_id=f"{order_id}-e{seq}", sequence_id=seq, released=True) for seq in edges
        ],
        agv_position=AgvPosition(
            x=pose[0], y=pose[1], theta=pose[2], map_id=pose[3], position_initialized=True
        )
        if pose
        else None,
        velocity=Velocity(vx=velocity[0], vy=velocity[1], omega=velocity[2]) if velocity else None,
        action_states=[
            ActionState(
                action_id=entry[0], action_status=entry[1], action_type=entry[2] if len(entry) > 2 else None
            )
            for entry in action_states
        ],
        battery_state=BatteryState(battery_charge=battery, charging=charging),
        errors=list(errors),
        safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
    )


IDLE_STATE = robot_state()


def on_order(
    order: OrderContent | dict[str, Any],
    reached: int = 0,
    *,
    action_status: ActionStatus | None = None,
    extra_actions: Iterable[tuple[str, ActionStatus] | tuple[str, ActionStatus, str]] = (),
    **fields: Any,
) -> State:
    """The robot holding `order`, having reached the node with sequenceId `reached`; the order's one
    action (if any) in `action_status`."""
    content = order if isinstance(order, OrderContent) else OrderContent.model_validate(order)
    actions = [(a.action_id, action_status, a.action_type) for n in content.nodes for a in n.actions]
    return robot_state(
        order_id=content.order_id,
        order_update_id=content.order_update_id,
        last_node_sequence_id=reached,
        node_states=[node.sequence_id for node in content.nodes if node.sequence_id > reached],
        action_states=[*(a for a in actions if a[1] is not None), *extra_actions],
        **fields,
    )


def finished(order: OrderContent | dict[str, Any], **fields: Any) -> State:
    """The robot at the end of `order`, idle, its action (if any) FINISHED."""
    content = order if isinstance(order, OrderContent) else OrderContent.model_validate(order)
    return on_order(content, content.nodes[-1].sequence_id, action_status=ActionStatus.FINISHED, **fields)


# --- running steps -------------------------------------------------------------------------------------


def checked_step(
    *,
    state: State | None,
    mission: MissionRecord | None,
    robot: RobotView | None = None,
    actions: list[ActionRecord] | None = None,
    now: datetime = NOW,
    state_arrived_at: datetime | None = None,
    settings: DispatchSettings = SETTINGS,
) -> StepResult:
    """`step`, with every emitted message checked against every schema version. The state arrived
    at `state_arrived_at`, by default just now."""
    result = step(
        now=now,
        robot=robot or robot_view(),
        state=state,
        state_arrived_at=state_arrived_at or now,
        mission=mission,
        actions=list(actions or []),
        settings=settings,
    )
    for header_id, message in enumerate(result.messages):
        check_schema(message.content, header_id, now)
    return result


def check_schema(content: OrderContent | InstantActionsContent, header_id: int, now: datetime) -> None:
    topic = "order" if isinstance(content, OrderContent) else "instantActions"
    for version in VERSIONS:
        header = header_for(RobotAddress("uagv", "RobotCompany", ROBOT, version), header_id=header_id, at=now)
        validate_message(topic, version, orjson.loads(encode(content, header)))


def orders_sent(result: StepResult) -> list[OrderContent]:
    return [m.content for m in result.messages if isinstance(m.content, OrderContent)]


def instant_actions_sent(result: StepResult) -> list[Action]:
    return [
        a for m in result.messages if isinstance(m.content, InstantActionsContent) for a in m.content.actions
    ]


def wire(content: OrderContent | InstantActionsContent) -> bytes:
    """The content as the robot receives it (fixed header), to compare messages byte for byte."""
    header = header_for(RobotAddress("uagv", "RobotCompany", ROBOT), header_id=0, at=NOW)
    return encode(content, header)


@dataclass
class Dispatcher:
    """Plays the caller (`robot_step`): feeds each result back, keeping only unfinished instant actions."""

    mission: MissionRecord | None
    robot: RobotView = field(default_factory=robot_view)
    actions: list[ActionRecord] = field(default_factory=list)
    now: datetime = NOW
    results: list[StepResult] = field(default_factory=list)
    settings: DispatchSettings = SETTINGS

    def step(
        self, state: State | None, *, after: float = 0.0, arrived_at: datetime | None = None
    ) -> StepResult:
        """One step `after` seconds later than the previous one, of a state that arrived at `arrived_at`
        (by default at the step)."""
        self.now += timedelta(seconds=after)
        result = checked_step(
            state=state,
            mission=self.mission,
            robot=self.robot,
            actions=self.actions,
            now=self.now,
            state_arrived_at=arrived_at,
            settings=self.settings,
        )
        self.mission = result.mission
        self.actions = [a for a in result.actions if a.status not in FINAL]
        self.robot = replace(self.robot, state=result.robot_state)
        self.results.append(result)
        return result

    @property
    def order(self) -> OrderContent:
        assert self.mission is not None and self.mission.order is not None
        return OrderContent.model_validate(self.mission.order)

    def node(self, name: str) -> str:
        assert self.mission is not None
        return self.mission.node_status[name]["state"]


def started(*tree: dict[str, Any], state: State = IDLE_STATE, **fields: Any) -> Dispatcher:
    """A dispatcher whose mission of `tree` has just started and sent its first order."""
    dispatcher = Dispatcher(mission(*tree, **fields))
    dispatcher.step(state)
    assert dispatcher.mission is not None and dispatcher.mission.state == MissionState.RUNNING
    return dispatcher


def cancel_actions(actions: Iterable[ActionRecord]) -> list[ActionRecord]:
    return [a for a in actions if a.action_type == ActionType.CANCEL_ORDER]
