"""The mission's order as sent: built from a leaf, stored on the mission, read back.

A running route leaf whose next leaf is certain to be a route (`dispatch.step._extend`) has that leaf sent
ahead, as an order update of its own order: the robot drives on from the route's last node instead of
stopping there for a new order. The stored order (`MissionRecord.order`) is then both, stitched
(`vda5050.orders.stitch`): its ids are the update's, its nodes and edges the running leaf's then the next
leaf's, each named after its leaf (`<mission>-n<index>-r<attempt>-s<sequenceId>`), which is how a step
tells them apart.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from dispatch import engine
from dispatch.vocabulary import NodeKind
from vda5050 import orders
from vda5050.models import Node, OrderContent


@dataclass(frozen=True)
class SentOrder:
    """A running mission's stored order, read: the message that carries the running leaf (a new order, or
    the order update that brought it), and the order update that carries the next leaf, if one was sent
    ahead. `stored` is what the robot should hold: both, stitched."""

    stored: OrderContent
    leaf: int  # the running leaf's index in mission_tree
    message: OrderContent
    ahead: OrderContent | None = None
    next_leaf: int | None = None

    @property
    def latest(self) -> OrderContent:
        """The latest message: the one the robot must take, re-sent identically while it lacks it."""
        return self.ahead or self.message


def sent_order(order: dict[str, Any]) -> SentOrder:
    """`MissionRecord.order` read into the running leaf's message and the order update sent ahead."""
    stored = OrderContent.model_validate(order)
    first, *rest = stored.nodes
    leaf = _leaf_of(rest[0] if rest else first)
    ahead = next((node for node in rest if _leaf_of(node) != leaf), None)
    if ahead is None:
        return SentOrder(stored, leaf, stored)
    message, update = orders.unstitch(stored, ahead.sequence_id - 2)
    return SentOrder(stored, leaf, message, update, _leaf_of(ahead))


def _leaf_of(node: Node) -> int:
    key = orders.order_key(node.node_id)
    assert key is not None, f"node {node.node_id} was not built by the dispatch engine"
    return key.node_index


def stored(order: OrderContent) -> dict[str, Any]:
    """The order as `MissionRecord.order` keeps it: its wire content."""
    return order.model_dump(mode="json", by_alias=True, exclude_none=True)


def build_order(
    mission: str,
    leaf: engine.Node,
    attempt: int,
    pose: orders.Pose,
    start_deviation_xy: float,
    *,
    tail: int | None = None,
) -> OrderContent:
    """The VDA 5050 order that executes a route, move or action leaf from the robot's pose; of a route,
    only its last `tail` waypoints (the rest a robot that lost the order resumes, `dispatch.faults`)."""
    assert leaf.index is not None
    common = {
        "mission": mission,
        "node_index": leaf.index,
        "attempt": attempt,
        "start": pose,
        "start_deviation_xy": start_deviation_xy,
    }
    if leaf.kind == NodeKind.ROUTE:
        waypoints = [_waypoint(wp) for wp in leaf.params["waypoints"]]
        return orders.route_order(waypoints=waypoints[-tail:] if tail else waypoints, **common)
    if leaf.kind == NodeKind.MOVE:
        return orders.move_order(
            distance=leaf.params.get("distance"), rotation=leaf.params.get("rotation"), **common
        )
    return orders.action_order(
        action_type=leaf.params["action_type"],
        parameters=leaf.params.get("action_parameters") or {},
        **common,
    )


def order_update_for(mission: str, previous: OrderContent, leaf: engine.Node, attempt: int) -> OrderContent:
    """The order update that extends `previous` at its last node with route `leaf`, its new nodes and edges
    named after the leaf."""
    assert leaf.index is not None
    return orders.order_update(
        previous,
        waypoints=[_waypoint(wp) for wp in leaf.params["waypoints"]],
        ids=orders.order_id(mission, leaf.index, attempt),
    )


def _waypoint(pose: dict[str, Any]) -> orders.Waypoint:
    return orders.Waypoint(
        x=float(pose.get("x", 0.0)),
        y=float(pose.get("y", 0.0)),
        theta=float(pose.get("theta", 0.0)),
        map_id=pose.get("map_id", ""),
        allowed_deviation_xy=float(pose.get("allowedDeviationXY", orders.DEFAULT_ALLOWED_DEVIATION_XY)),
        allowed_deviation_theta=float(
            pose.get("allowedDeviationTheta", orders.DEFAULT_ALLOWED_DEVIATION_THETA)
        ),
    )
