"""The records a dispatch step reads and returns: the stored robot, mission and instant actions, the
messages to send. Plain dataclasses, no I/O."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from dispatch.vocabulary import DONE_STATES
from vda5050 import compat
from vda5050.codec import ACTIONS_KEY
from vda5050.models import (
    InstantActionsContent,
    OrderContent,
    ResponsesContent,
    ZoneSetContent,
)
from vda5050.topics import Topic


@dataclass(frozen=True)
class DispatchSettings:
    order_resend: timedelta
    instant_action_resend: timedelta
    start_deviation_xy: float
    # A robot that holds its order and shows no progress on it for this long has it canceled and the rest
    # sent anew (`dispatch.faults`); zero turns the check off.
    order_stall: timedelta = timedelta(0)


@dataclass(frozen=True)
class ZoneReach:
    """What the zone plan (`dispatch.zones.decide`, stored by `missions.zone_plan`) allows a robot while
    some map has an enabled RELEASE zone; a robot without one (None) is not held back by zones at all. A
    robot the plan has not seen yet on a map with an enabled RELEASE zone gets the empty reach: nothing but
    starts.

    Its order's base may hold the nodes of order `order_id` up to sequenceId `release_through`: of any
    other order (a new one, before the plan has seen it), no node beyond the robot's own position."""

    order_id: str | None = None
    release_through: int | None = None
    waiting: tuple[str, ...] = ()  # the zone ids it waits for at the edge of its next leg
    responses: tuple[tuple[str, str], ...] = ()  # answers to its 3.0 zoneRequests: (requestId, grantType)
    responses_due: bool = False  # answers the robot was not sent yet

    def through(self, order_id: str) -> int:
        """How far the base of order `order_id` may reach (a sequenceId; 0: its first node alone)."""
        if order_id != self.order_id or self.release_through is None:
            return 0
        return self.release_through


@dataclass(frozen=True)
class RobotView:
    name: str
    lifecycle: str
    state: str
    online: bool
    battery_critical_level: float
    charge_threshold: float | None = None  # at or below it, it charges first (`missions.rows`); None: never
    switch_teleop: bool = False  # teleop asked for through the API (not by a pause_order action)
    instant_actions_key: str = ACTIONS_KEY
    instant_actions_key_by_operator: bool = False  # then no compatibility rule changes it
    routes_ahead: bool = True  # False once compat.Rule.ORDER_UPDATE_NOT_EXECUTED applied to the robot
    zone_reach: ZoneReach | None = None  # how far zones let its orders reach; None: no zones to mind


@dataclass
class MissionRecord:
    """The stored fields of a mission that a step reads or writes."""

    name: str
    mission_tree: list[dict[str, Any]]
    timeout: float
    deadline: datetime | None
    needs_canceled: bool
    update_nodes: dict[str, Any] | None
    lifecycle: str
    state: str
    current_node: int
    node_status: dict[str, dict[str, Any]]
    task_status: dict[str, int]
    start_timestamp: datetime | None
    end_timestamp: datetime | None
    failure_reason: str | None
    failure_category: str | None
    waiting_reason: str | None
    order: dict[str, Any] | None
    order_sent_at: datetime | None
    order_accepted: bool
    attempts: dict[str, int]
    # The robot's progress on the order as a step last saw it change (`dispatch.faults.progress_mark`),
    # and when: the stall clock, and how far a route got when the robot lost its order.
    progress: dict[str, Any] | None = None
    progress_seen_at: datetime | None = None
    # The bindings assignment made (issue 41): not empty for a mission posted without a robot.
    assignment: list[dict[str, Any]] = field(default_factory=list)
    # A trip the dispatch core made (`MissionPurpose`): a CHARGE trip starts below the critical level.
    purpose: str | None = None

    @property
    def done(self) -> bool:
        return self.state in DONE_STATES


@dataclass
class ActionRecord:
    """An instant action sent (or to be sent: `sent_at` None) and not yet reported final."""

    action_id: str
    action_type: str
    mission: str | None
    status: str | None
    sent_at: datetime | None
    send_count: int = 0
    parameters: dict[str, Any] | None = None  # its actionParameters as a mapping (map actions have some)


@dataclass(frozen=True)
class Outgoing:
    """A message to publish to the robot: an order, instant actions or (3.0) a zone set (header stamped
    when sent)."""

    content: OrderContent | InstantActionsContent | ZoneSetContent | ResponsesContent

    @property
    def topic(self) -> Topic:
        """The topic it goes out on; each topic numbers its messages (headerId) on its own."""
        if isinstance(self.content, OrderContent):
            return Topic.ORDER
        if isinstance(self.content, ResponsesContent):
            return Topic.RESPONSES
        return Topic.ZONE_SET if isinstance(self.content, ZoneSetContent) else Topic.INSTANT_ACTIONS


@dataclass
class StepResult:
    robot_state: str
    mission: MissionRecord | None
    delete_mission: bool = False
    delete_robot: bool = False
    actions: list[ActionRecord] = field(default_factory=list)
    messages: list[Outgoing] = field(default_factory=list)
    notify: str | None = None  # name of a notify node to run now
    switch_teleop: bool = False  # the robot's API teleop switch, which a mission's end leaves alone
    rejected: bool = False  # the robot rejected an order (counted by the caller)
    instant_actions_key: str | None = None  # the key the robot turned out to read, if it changed
    rules_applied: list[tuple[compat.Rule, str]] = field(default_factory=list)  # (rule, why), to record
    # What the mission was between two leaves that ran and ended within this step (a route sent ahead that
    # the robot drove to its end before a step saw it start), oldest first: stored before `mission`, so
    # every leaf is seen RUNNING, as when each leaf was sent in its own step.
    passed: list[MissionRecord] = field(default_factory=list)
    # Why the robot gives back the queued mission assignment bound to it (offline, low battery, a FATAL
    # error, being deleted): it is unbound again, for another robot.
    release: str | None = None
    # The zone plan should run (`missions.zone_plan`): the robot's route or position on it changed, its
    # mission ended, or its 3.0 zone requests are not the ones last answered.
    zones_plan: bool = False
