"""Whether a simulated robot takes an order: the acceptance algorithm of VDA 5050 2.1 (Figure 8), strict
wherever the document allows.

A malformed order, a new order while busy or far from its first node, an outdated or unstitchable
update are rejected with a WARNING in ``errors`` that references the order; an exact duplicate is
discarded silently. ``failure_period`` makes every Nth accepted order fail on purpose. Instant-actions
messages pass the same addressee check (``check_addressee``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from simulator.config import RobotConfig, SimulationSettings, Stack
from simulator.errors import (
    ORDER_ERROR,
    ORDER_UPDATE_ERROR,
    SIMULATED_FAILURE,
    VALIDATION_ERROR,
    ErrorReport,
    Rejection,
    order_references,
    raw_references,
)
from simulator.maps import RobotMaps
from simulator.motion import Drive, target_of
from simulator.orders import CurrentOrder
from vda5050.codec import parse_order
from vda5050.errors import ProtocolError
from vda5050.models import ErrorLevel, Header, Node, Order
from vda5050.orders import check_order_graph
from vda5050.topics import RobotAddress, Topic, major_version_of

FAILURE_PERIOD_REACHED = "Failure period reached"


@dataclass(eq=False)
class OrderAcceptance:
    """Takes, updates, discards or rejects each order the robot receives."""

    config: RobotConfig
    settings: SimulationSettings
    address: RobotAddress
    order: CurrentOrder
    maps: RobotMaps
    drive: Drive
    errors: ErrorReport
    accepted_orders: int = field(default=0, init=False)  # failure_period counts them

    def receive(self, payload: bytes) -> None:
        try:
            order = parse_order(payload)
        except ProtocolError as exc:
            self.errors.warn(VALIDATION_ERROR, str(exc), raw_references(Topic.ORDER, payload))
            return
        try:
            self._take(order)
        except Rejection as exc:
            self.errors.warn(exc.error_type, exc.description, order_references(order))

    def _take(self, order: Order) -> None:
        check_addressee(order, self.config, self.address)
        problems = check_order_graph(order)
        if not order.order_id:
            problems.insert(0, "orderId is empty")
        if problems:
            raise Rejection(VALIDATION_ERROR, "; ".join(problems))
        check_usable(order)
        self.maps.check_order(order)
        current = self.order
        if order.order_id != current.order_id:
            self._start(order)
        elif order.order_update_id < current.order_update_id:
            raise Rejection(
                ORDER_UPDATE_ERROR,
                f"orderUpdateId {order.order_update_id} is lower than the current {current.order_update_id}",
            )
        elif order.order_update_id > current.order_update_id:
            current.update(order, executed=self.config.stack != Stack.VDA5050_SDK_0_2)
        # an equal orderUpdateId is a resend of what the robot already has: discarded silently

    def _start(self, order: Order) -> None:
        if self.order.busy():
            raise Rejection(
                ORDER_ERROR,
                f"busy: order {self.order.order_id!r} is not finished (node states left or actions not"
                " FINISHED/FAILED); cancel it first",
            )
        first = order.nodes[0]
        if first.sequence_id != 0:
            raise Rejection(VALIDATION_ERROR, f"a new order starts at sequenceId 0, not {first.sequence_id}")
        self._check_start_node(first)
        self.errors.clear()
        self.order.start(order)
        self.accepted_orders += 1
        failure_period = self.config.failure_period
        if failure_period and self.accepted_orders % failure_period == 0:
            self._fail_on_purpose()

    def _check_start_node(self, node: Node) -> None:
        """The first node must be trivially reachable: the robot stands on it or within its range."""
        position = node.node_position
        if position is None:
            if node.node_id != self.order.last_node_id:
                raise Rejection(
                    ORDER_ERROR,
                    f"first node {node.node_id!r} has no nodePosition and is not the last node"
                    f" {self.order.last_node_id!r}",
                )
            return
        if position.map_id != self.maps.map_id:
            raise Rejection(
                ORDER_ERROR,
                f"first node {node.node_id!r} is on map {position.map_id!r}, robot on {self.maps.map_id!r}",
            )
        target = target_of(node)
        pose = self.drive.pose
        if not target.within_xy(pose):
            distance = math.hypot(target.x - pose.x, target.y - pose.y)
            raise Rejection(
                ORDER_ERROR,
                f"first node {node.node_id!r} is out of range: {distance:.3f} m from the robot, allowed"
                f" {target.deviation_xy} m",
            )

    def _fail_on_purpose(self) -> None:
        """``failure_period``: every Nth order fails (FATAL: abandoned) or only warns and goes on."""
        level = ErrorLevel.WARNING if self.settings.fail_as_warning else ErrorLevel.FATAL
        self.errors.add(
            SIMULATED_FAILURE,
            FAILURE_PERIOD_REACHED,
            level,
            [("nodeId", self.order.last_node_id), ("orderId", self.order.order_id)],
        )
        if level == ErrorLevel.FATAL:
            self.order.drop(FAILURE_PERIOD_REACHED)
            self.drive.stop()


def check_addressee(message: Header, config: RobotConfig, address: RobotAddress) -> None:
    """An order or instant-actions message must name this robot and its major version."""
    if (message.manufacturer, message.serial_number) != (config.manufacturer, config.serial):
        raise Rejection(
            VALIDATION_ERROR,
            f"addressed to manufacturer {message.manufacturer!r} serialNumber {message.serial_number!r},"
            f" this robot is {config.manufacturer!r} {config.serial!r}",
        )
    try:
        major = major_version_of(message.version)
    except ProtocolError as exc:
        raise Rejection(VALIDATION_ERROR, str(exc)) from None
    if major != address.major_version:
        raise Rejection(VALIDATION_ERROR, f"version {message.version} is not {address.version}")


def check_usable(order: Order) -> None:
    """Fields the robot cannot follow make it reject the order instead of silently ignoring them."""
    for index, node in enumerate(order.nodes[1:], start=1):
        if node.node_position is None:
            raise Rejection(ORDER_ERROR, f"nodes[{index}] ({node.node_id!r}) has no nodePosition")
    for index, edge in enumerate(order.edges):
        for field_name in ("trajectory", "corridor"):
            if getattr(edge, field_name) is not None:
                raise Rejection(ORDER_ERROR, f"edges[{index}].{field_name} is not supported")
