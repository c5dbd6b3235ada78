"""The order a simulated robot holds, and how an update joins it (stitching at the decision point).

What the order says is taken as given here: ``simulator.acceptance`` decides whether an order is taken.
"""

from __future__ import annotations

from collections import deque

from simulator.actions import ActionRun
from simulator.errors import ORDER_UPDATE_ERROR, VALIDATION_ERROR, Rejection
from simulator.outbox import Outbox
from vda5050.models import Edge, EdgeState, Node, NodeState, Order


class CurrentOrder:
    """The robot's order: the nodes and edges still ahead (base then horizon), the last node traversed,
    and every action the robot knows of (``actionStates``, instant actions included) and which runs."""

    def __init__(self, outbox: Outbox) -> None:
        self.order_id = ""
        self.order_update_id = 0
        self.zone_set_id: str | None = None  # echoed as the document asks; zones are not simulated
        self.last_node_id = ""
        self.last_node_sequence_id = 0
        self.nodes: list[Node] = []  # still to traverse, base then horizon
        self.edges: list[Edge] = []
        self.runs: dict[str, ActionRun] = {}  # actionStates, in arrival order
        self.queue: deque[str] = deque()  # actionIds to run here, one after another
        self.running: str | None = None
        self.entered_edge: int | None = None  # sequenceId of the edge whose actions were queued
        # Stack.VDA5050_SDK_0_2: the sequenceId it stands still at, having taken an update it never executes
        self.halt_at: int | None = None
        self._outbox = outbox

    def start(self, order: Order) -> None:
        """Take a new order, standing on its first node (acceptance checked that it may)."""
        self.order_id = order.order_id
        self.order_update_id = order.order_update_id
        self.zone_set_id = order.zone_set_id
        self.nodes = list(order.nodes[1:])
        self.edges = list(order.edges)
        self.runs = {
            action.action_id: ActionRun(action)
            for element in (*order.nodes, *order.edges)
            for action in element.actions
        }
        self.queue.clear()
        self.running = None
        self.entered_edge = None
        self.halt_at = None
        self.arrive(order.nodes[0])

    def update(self, order: Order, *, executed: bool = True) -> None:
        """Stitch at the decision point: keep the base, replace the horizon, append the rest. Not
        ``executed`` (``Stack.VDA5050_SDK_0_2``): reported as taken, but the robot halts at the decision
        point."""
        first = order.nodes[0]
        decision_point = self.decision_point()
        if (first.node_id, first.sequence_id) != decision_point:
            raise Rejection(
                ORDER_UPDATE_ERROR,
                f"update starts at node {first.node_id!r} (sequenceId {first.sequence_id}), not at the"
                f" decision point {decision_point[0]!r} (sequenceId {decision_point[1]})",
            )
        horizon = [element for element in (*self.nodes, *self.edges) if not element.released]
        horizon_action_ids = {action.action_id for element in horizon for action in element.actions}
        # the stitching node's content is the robot's already (2.x): its actions are not taken again
        new_actions = [action for element in (*order.nodes[1:], *order.edges) for action in element.actions]
        reused = [a.action_id for a in new_actions if a.action_id in self.runs.keys() - horizon_action_ids]
        if reused:
            raise Rejection(VALIDATION_ERROR, f"actionIds already used in this order: {', '.join(reused)}")
        for action_id in horizon_action_ids:
            self.runs.pop(action_id, None)
        self.nodes = [node for node in self.nodes if node.released] + list(order.nodes[1:])
        self.edges = [edge for edge in self.edges if edge.released] + list(order.edges)
        self.runs.update((action.action_id, ActionRun(action)) for action in new_actions)
        self.order_update_id = order.order_update_id
        self.zone_set_id = order.zone_set_id
        if not executed and self.halt_at is None:
            self.halt_at = decision_point[1]
        self._outbox.state_changed = True

    def halted(self) -> bool:
        """Standing still at ``halt_at`` with the rest of the order ahead."""
        return self.halt_at is not None and self.last_node_sequence_id >= self.halt_at

    def decision_point(self) -> tuple[str, int]:
        """Last released node still ahead, else the node last reached."""
        released = [node for node in self.nodes if node.released]
        if released:
            return released[-1].node_id, released[-1].sequence_id
        return self.last_node_id, self.last_node_sequence_id

    def busy(self, besides: ActionRun | None = None) -> bool:
        """Nodes or edges left, or an action (other than ``besides``) not FINISHED/FAILED."""
        return bool(self.nodes or self.edges) or any(
            not run.done for run in self.runs.values() if run is not besides
        )

    def new_base_request(self) -> bool:
        """A horizon waits and at most the decision point is left of the base."""
        released_ahead = sum(node.released for node in self.nodes)
        return released_ahead <= 1 and any(not node.released for node in self.nodes)

    def arrive(self, node: Node) -> None:
        """Node traversed: drop it (and the edge before it) from the states, queue its actions."""
        self.last_node_id = node.node_id
        self.last_node_sequence_id = node.sequence_id
        self.edges = [edge for edge in self.edges if edge.sequence_id > node.sequence_id]
        self.queue.extend(action.action_id for action in node.actions)
        self._outbox.state_changed = True

    def drop(self, reason: str, besides: ActionRun | None = None) -> None:
        """Abandon the rest: unfinished actions (but ``besides``) FAILED, node/edge states emptied,
        orderId kept. The caller stops the robot as well (``Drive.stop``)."""
        for run in self.runs.values():
            if run is not besides and not run.done:
                run.fail(reason)
        self.nodes = []
        self.edges = []
        self.queue.clear()
        self.running = None
        self.entered_edge = None
        self.halt_at = None

    def node_states(self) -> list[NodeState]:
        return [
            NodeState(
                node_id=node.node_id,
                sequence_id=node.sequence_id,
                node_description=node.node_description,
                released=node.released,
                node_position=node.node_position,
            )
            for node in self.nodes
        ]

    def edge_states(self) -> list[EdgeState]:
        return [
            EdgeState(
                edge_id=edge.edge_id,
                sequence_id=edge.sequence_id,
                edge_description=edge.edge_description,
                released=edge.released,
                trajectory=edge.trajectory,
            )
            for edge in self.edges
        ]
