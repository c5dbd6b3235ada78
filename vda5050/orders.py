"""Pure order building and checking.

Ids are derived from (mission, mission-tree node index, attempt), so building the same order twice gives
identical content and a resend is recognised by the robot as a duplicate. Within one order, node ids are
``<orderId>-s<sequenceId>``, edge ids ``<orderId>-e<sequenceId>`` and action ids ``<orderId>-a<k>``;
since orderIds differ between orders, all of them are unique across orders as well. An order update may
name its new nodes and edges after another key (``order_update``'s ``ids``: the dispatch step names them
after the mission-tree leaf they carry), so every element id still says which leaf it belongs to.
"""

from __future__ import annotations

import math
import re
import uuid
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from vda5050.models import (
    Action,
    ActionParameter,
    ActionType,
    BlockingType,
    Edge,
    InstantActionsContent,
    Node,
    NodePosition,
    OrderContent,
)
from vda5050.topics import check_id

# The start node is where the robot already stands; a generous radius lets a strict AGV accept it
# although its reported pose is a little stale.
DEFAULT_START_DEVIATION_XY = 0.5  # m
DEFAULT_ALLOWED_DEVIATION_XY = 0.1  # m
DEFAULT_ALLOWED_DEVIATION_THETA = 0.0  # rad
MAX_ALLOWED_DEVIATION_THETA = math.pi  # the document's range is [0, pi]
ORDER_ACTION_BLOCKING = BlockingType.HARD
# 2.x leaves instant actions' blocking type open; 3.0 makes it NONE, which no AGV will find too strict.
INSTANT_ACTION_BLOCKING = BlockingType.NONE

ORDER_KEY_PATTERN = re.compile(r"(?P<mission>.+)-n(?P<node_index>\d+)-r(?P<attempt>\d+)(?:-[sea]\d+)?")


@dataclass(frozen=True)
class Pose:
    """Where the robot is now (from its last state)."""

    x: float
    y: float
    theta: float
    map_id: str = ""


@dataclass(frozen=True)
class Waypoint:
    """A target node position with the tolerance that counts as reaching it."""

    x: float
    y: float
    theta: float
    map_id: str
    allowed_deviation_xy: float = DEFAULT_ALLOWED_DEVIATION_XY
    allowed_deviation_theta: float = DEFAULT_ALLOWED_DEVIATION_THETA

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.x, self.y, self.theta)):
            raise ValueError("waypoint coordinates must be finite numbers")
        if not self.allowed_deviation_xy >= 0:
            raise ValueError(f"allowed_deviation_xy {self.allowed_deviation_xy} must be >= 0")
        if not 0 <= self.allowed_deviation_theta <= MAX_ALLOWED_DEVIATION_THETA:
            raise ValueError(f"allowed_deviation_theta {self.allowed_deviation_theta} must be in [0, pi]")


class OrderKey(NamedTuple):
    """What an order id encodes."""

    mission: str
    node_index: int
    attempt: int


# --- ids -------------------------------------------------------------------------------------------


def order_id(mission: str, node_index: int, attempt: int) -> str:
    check_id("mission", mission)
    if node_index < 0 or attempt < 0:
        raise ValueError("node_index and attempt must be >= 0")
    return f"{mission}-n{node_index}-r{attempt}"


def node_id(order: str, sequence_id: int) -> str:
    return f"{order}-s{sequence_id}"


def edge_id(order: str, sequence_id: int) -> str:
    return f"{order}-e{sequence_id}"


def action_id(order: str, index: int) -> str:
    return f"{order}-a{index}"


def order_key(element_id: str) -> OrderKey | None:
    """Mission, node index and attempt from an orderId or one of our node, edge or action ids.

    Robots reference failing nodes/actions in error references; this maps them back to the mission.
    """
    match = ORDER_KEY_PATTERN.fullmatch(element_id)
    if match is None:
        return None
    return OrderKey(match["mission"], int(match["node_index"]), int(match["attempt"]))


def new_action_id(prefix: str) -> str:
    """A unique id for an instant action (unlike order actions, these are not resent verbatim)."""
    check_id("prefix", prefix)
    return f"{prefix}-{uuid.uuid4()}"


# --- orders ----------------------------------------------------------------------------------------


def route_order(
    *,
    mission: str,
    node_index: int,
    attempt: int,
    start: Pose,
    waypoints: Sequence[Waypoint],
    horizon: Sequence[Waypoint] = (),
    start_deviation_xy: float = DEFAULT_START_DEVIATION_XY,
) -> OrderContent:
    """Drive from the current pose through ``waypoints`` (base), announcing ``horizon`` (not released)."""
    order = order_id(mission, node_index, attempt)
    map_id = start.map_id or next((wp.map_id for wp in (*waypoints, *horizon)), "")
    first = _start_node(order, start, map_id, start_deviation_xy)
    nodes, edges = _chain(order, first, waypoints, horizon)
    return OrderContent(order_id=order, order_update_id=0, nodes=nodes, edges=edges)


def move_order(
    *,
    mission: str,
    node_index: int,
    attempt: int,
    start: Pose,
    distance: float | None = None,
    rotation: float | None = None,
    allowed_deviation_xy: float = DEFAULT_ALLOWED_DEVIATION_XY,
    allowed_deviation_theta: float = DEFAULT_ALLOWED_DEVIATION_THETA,
    start_deviation_xy: float = DEFAULT_START_DEVIATION_XY,
) -> OrderContent:
    """Drive ``distance`` metres along the current heading, or turn by ``rotation`` radians in place."""
    if (distance is None) == (rotation is None):
        raise ValueError("give exactly one of distance and rotation")
    if distance is not None:
        x = start.x + distance * math.cos(start.theta)
        y = start.y + distance * math.sin(start.theta)
        theta = start.theta
    else:
        x, y, theta = start.x, start.y, start.theta + rotation
    target = Waypoint(x, y, theta, start.map_id, allowed_deviation_xy, allowed_deviation_theta)
    return route_order(
        mission=mission,
        node_index=node_index,
        attempt=attempt,
        start=start,
        waypoints=[target],
        start_deviation_xy=start_deviation_xy,
    )


def action_order(
    *,
    mission: str,
    node_index: int,
    attempt: int,
    start: Pose,
    action_type: str,
    parameters: Mapping[str, Any],
    blocking_type: BlockingType = ORDER_ACTION_BLOCKING,
    start_deviation_xy: float = DEFAULT_START_DEVIATION_XY,
) -> OrderContent:
    """One node at the current pose carrying one action; parameters keep their JSON types."""
    order = order_id(mission, node_index, attempt)
    node = _start_node(order, start, start.map_id, start_deviation_xy)
    node.actions.append(
        Action(
            action_type=action_type,
            action_id=action_id(order, 0),
            blocking_type=blocking_type,
            action_parameters=action_parameters(parameters),
        )
    )
    return OrderContent(order_id=order, order_update_id=0, nodes=[node], edges=[])


def order_update(
    previous: OrderContent,
    *,
    waypoints: Sequence[Waypoint],
    horizon: Sequence[Waypoint] = (),
    ids: str | None = None,
) -> OrderContent:
    """Extend ``previous`` (the latest update sent, or the order as the robot holds it) from its decision
    point.

    The decision point (last released node) is repeated unchanged, with its full content (as 3.0 asks;
    2.x robots keep theirs), older base elements are not resent, the previous horizon is replaced by
    ``horizon`` (dropped when empty) and sequenceIds continue. The new nodes and edges are named
    ``<ids>-s<sequenceId>``/``<ids>-e<sequenceId>`` (default: the orderId).
    """
    decision_point = last_base_node(previous).model_copy(deep=True)
    nodes, edges = _chain(ids or previous.order_id, decision_point, waypoints, horizon)
    return OrderContent(
        order_id=previous.order_id,
        order_update_id=previous.order_update_id + 1,
        zone_set_id=previous.zone_set_id,
        nodes=nodes,
        edges=edges,
    )


def stitch(order: OrderContent, update: OrderContent) -> OrderContent:
    """The order as a robot holds it once it took ``update``: ``order``'s base, then the update's nodes and
    edges after the decision point, under the update's ids (what it replaced of the horizon is gone)."""
    decision_point = last_base_node(order)
    first = update.nodes[0]
    if (update.order_id, first.node_id, first.sequence_id) != (
        order.order_id,
        decision_point.node_id,
        decision_point.sequence_id,
    ):
        raise ValueError(
            f"update {update.order_update_id} does not start at {order.order_id}'s decision point"
        )
    nodes = [node for node in order.nodes if node.sequence_id <= first.sequence_id] + update.nodes[1:]
    edges = [edge for edge in order.edges if edge.sequence_id < first.sequence_id] + update.edges
    return update.model_copy(update={"nodes": nodes, "edges": edges}, deep=True)


def unstitch(order: OrderContent, sequence_id: int) -> tuple[OrderContent, OrderContent]:
    """``stitch`` undone for an order whose last update extended it at the node ``sequence_id``: the order
    as it was before that update (numbered one lower), and the update as it was sent."""
    nodes = [node for node in order.nodes if node.sequence_id <= sequence_id]
    if not nodes or nodes[-1].sequence_id != sequence_id or order.order_update_id < 1:
        raise ValueError(f"order {order.order_id!r} was not extended at sequenceId {sequence_id}")
    before = order.model_copy(
        update={
            "order_update_id": order.order_update_id - 1,
            "nodes": nodes,
            "edges": [edge for edge in order.edges if edge.sequence_id < sequence_id],
        },
        deep=True,
    )
    update = order.model_copy(
        update={
            "nodes": [node for node in order.nodes if node.sequence_id >= sequence_id],
            "edges": [edge for edge in order.edges if edge.sequence_id > sequence_id],
        },
        deep=True,
    )
    return before, update


def hold_back(order: OrderContent, through: int) -> OrderContent:
    """``order`` with its base ending at the node of sequenceId ``through`` (its first node at least):
    what lies beyond is announced as horizon, not released."""
    return order.model_copy(
        update={
            "nodes": [
                node.model_copy(update={"released": node.released and node.sequence_id <= through})
                for node in order.nodes
            ],
            "edges": [
                edge.model_copy(update={"released": edge.released and edge.sequence_id < through})
                for edge in order.edges
            ],
        },
        deep=True,
    )


def release_update(order: OrderContent, through: int) -> OrderContent:
    """The order update that extends ``order``'s base (as the robot holds it) through its horizon node of
    sequenceId ``through``: the decision point, then the horizon's nodes and edges as they were announced,
    released up to ``through``, the rest still horizon. ``stitch`` makes it the order the robot holds."""
    decision_point = last_base_node(order)
    beyond = decision_point.sequence_id
    return OrderContent(
        order_id=order.order_id,
        order_update_id=order.order_update_id + 1,
        zone_set_id=order.zone_set_id,
        nodes=[
            decision_point.model_copy(deep=True),
            *(
                node.model_copy(update={"released": node.sequence_id <= through}, deep=True)
                for node in order.nodes
                if node.sequence_id > beyond
            ),
        ],
        edges=[
            edge.model_copy(update={"released": edge.sequence_id < through}, deep=True)
            for edge in order.edges
            if edge.sequence_id > beyond
        ],
    )


def last_base_node(order: OrderContent) -> Node:
    """The decision point: the robot stops there unless the base is extended."""
    released = [node for node in order.nodes if node.released]
    if not released:
        raise ValueError(f"order {order.order_id!r} has no released node")
    return released[-1]


def normalize_angle(theta: float) -> float:
    """Into [-pi, pi], the range the schema allows for theta; in-range values stay bit-identical."""
    return math.remainder(theta, math.tau)


def action_parameters(parameters: Mapping[str, Any]) -> list[ActionParameter] | None:
    """Key-sorted parameters with key-sorted objects inside, so equal mappings give equal bytes
    (a mapping read back from a JSON column need not keep its key order)."""
    if not parameters:
        return None
    return [ActionParameter(key=key, value=_canonical(parameters[key])) for key in sorted(parameters)]


def _canonical(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {key: _canonical(value[key]) for key in sorted(value)}
    if isinstance(value, list | tuple):
        return [_canonical(item) for item in value]
    return value


def _start_node(order: str, start: Pose, map_id: str, deviation_xy: float) -> Node:
    """The robot's current position; no theta, so no AGV turns before it sets off."""
    position = NodePosition(x=start.x, y=start.y, map_id=map_id, allowed_deviation_xy=deviation_xy)
    return Node(node_id=node_id(order, 0), sequence_id=0, released=True, node_position=position, actions=[])


def _chain(
    order: str, first: Node, base: Sequence[Waypoint], horizon: Sequence[Waypoint]
) -> tuple[list[Node], list[Edge]]:
    """``first`` then edge, node, edge, node ... with sequenceIds continuing from ``first``."""
    nodes, edges = [first], []
    targets = [(waypoint, True) for waypoint in base] + [(waypoint, False) for waypoint in horizon]
    for waypoint, released in targets:
        previous = nodes[-1]
        sequence_id = previous.sequence_id + 2
        node = _waypoint_node(order, sequence_id, waypoint, released)
        edges.append(
            Edge(
                edge_id=edge_id(order, sequence_id - 1),
                sequence_id=sequence_id - 1,
                released=released,
                start_node_id=previous.node_id,
                end_node_id=node.node_id,
                actions=[],
            )
        )
        nodes.append(node)
    return nodes, edges


def _waypoint_node(order: str, sequence_id: int, waypoint: Waypoint, released: bool) -> Node:
    position = NodePosition(
        x=waypoint.x,
        y=waypoint.y,
        theta=normalize_angle(waypoint.theta),
        map_id=waypoint.map_id,
        allowed_deviation_xy=waypoint.allowed_deviation_xy,
        allowed_deviation_theta=waypoint.allowed_deviation_theta,
    )
    return Node(
        node_id=node_id(order, sequence_id),
        sequence_id=sequence_id,
        released=released,
        node_position=position,
        actions=[],
    )


# --- instant actions -------------------------------------------------------------------------------


def instant_action(
    action_type: str,
    action_id: str,
    parameters: Mapping[str, Any] | None = None,
    blocking_type: BlockingType = INSTANT_ACTION_BLOCKING,
) -> Action:
    return Action(
        action_type=action_type,
        action_id=action_id,
        blocking_type=blocking_type,
        action_parameters=action_parameters(parameters or {}),
    )


def instant_actions(actions: Iterable[Action]) -> InstantActionsContent:
    return InstantActionsContent(actions=list(actions))


def cancel_order(action_id: str) -> Action:
    return instant_action(ActionType.CANCEL_ORDER, action_id)


def start_pause(action_id: str) -> Action:
    return instant_action(ActionType.START_PAUSE, action_id)


def stop_pause(action_id: str) -> Action:
    return instant_action(ActionType.STOP_PAUSE, action_id)


def state_request(action_id: str) -> Action:
    return instant_action(ActionType.STATE_REQUEST, action_id)


def factsheet_request(action_id: str) -> Action:
    return instant_action(ActionType.FACTSHEET_REQUEST, action_id)


def start_teleop(action_id: str) -> Action:
    return instant_action(ActionType.START_TELEOP, action_id)


def stop_teleop(action_id: str) -> Action:
    return instant_action(ActionType.STOP_TELEOP, action_id)


# --- checking --------------------------------------------------------------------------------------


def check_order_graph(order: OrderContent) -> list[str]:
    """The document's graph rules that the schema cannot express; an empty list means valid.

    nodeIds and edgeIds may repeat (a loop visits a node twice; sequenceIds tell the visits apart),
    actionIds may not.
    """
    if not order.nodes:
        return ["nodes: an order needs at least one node"]
    problems = []
    if len(order.edges) != len(order.nodes) - 1:
        problems.append(f"edges: {len(order.edges)} edges for {len(order.nodes)} nodes, expected nodes - 1")
    for check in (_sequence_problems, _link_problems, _release_problems, _id_problems):
        problems += check(order)
    return problems


def _sequence_problems(order: OrderContent) -> list[str]:
    first = order.nodes[0].sequence_id
    problems = [] if first % 2 == 0 else [f"nodes[0].sequenceId {first} is odd; nodes carry even ones"]
    for i, node in enumerate(order.nodes):
        if node.sequence_id != first + 2 * i:
            problems.append(f"nodes[{i}].sequenceId is {node.sequence_id}, expected {first + 2 * i}")
    for i, edge in enumerate(order.edges):
        if edge.sequence_id != first + 2 * i + 1:
            problems.append(f"edges[{i}].sequenceId is {edge.sequence_id}, expected {first + 2 * i + 1}")
    return problems


def _link_problems(order: OrderContent) -> list[str]:
    problems = []
    for i, (edge, start, end) in enumerate(zip(order.edges, order.nodes, order.nodes[1:], strict=False)):
        if edge.start_node_id != start.node_id:
            problems.append(f"edges[{i}].startNodeId is {edge.start_node_id!r}, expected {start.node_id!r}")
        if edge.end_node_id != end.node_id:
            problems.append(f"edges[{i}].endNodeId is {edge.end_node_id!r}, expected {end.node_id!r}")
    return problems


def _release_problems(order: OrderContent) -> list[str]:
    """Base first, then horizon; an edge is released only together with both its nodes."""
    problems = [] if order.nodes[0].released else ["nodes[0].released must be true (start or decision point)"]
    horizon_started = False
    for name, released in _traversal(order):
        if released and horizon_started:
            problems.append(f"{name}.released is true after an unreleased element")
        horizon_started = horizon_started or not released
    for i, (edge, end) in enumerate(zip(order.edges, order.nodes[1:], strict=False)):
        if edge.released and not end.released:
            problems.append(f"edges[{i}] is released but its end node nodes[{i + 1}] is not")
    return problems


def _traversal(order: OrderContent) -> list[tuple[str, bool]]:
    """(name, released) of nodes and edges in traversal order: node, edge, node, ..."""
    elements = []
    for i, node in enumerate(order.nodes):
        elements.append((f"nodes[{i}]", node.released))
        if i < len(order.edges):
            elements.append((f"edges[{i}]", order.edges[i].released))
    surplus = order.edges[len(order.nodes) :]
    elements += [(f"edges[{len(order.nodes) + i}]", edge.released) for i, edge in enumerate(surplus)]
    return elements


def _id_problems(order: OrderContent) -> list[str]:
    problems = [f"nodes[{i}].nodeId is empty" for i, node in enumerate(order.nodes) if not node.node_id]
    problems += [f"edges[{i}].edgeId is empty" for i, edge in enumerate(order.edges) if not edge.edge_id]
    seen: set[str] = set()
    for action in [a for node in order.nodes for a in node.actions] + [
        a for edge in order.edges for a in edge.actions
    ]:
        if not action.action_id:
            problems.append(f"actionId of a {action.action_type!r} action is empty")
        elif action.action_id in seen:
            problems.append(f"actionId {action.action_id!r} is not unique")
        seen.add(action.action_id)
    return problems
