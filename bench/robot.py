"""A fake VDA 5050 2.0.0 robot built for speed: pure (no I/O), states as pre-serialized JSON.

The state body (everything but ``headerId`` and ``timestamp``) is serialized once per change, so a
periodic state costs one bytes formatting. Orders are read as plain dicts: the robot never rejects one,
so it needs nothing beyond ids, sequence ids and the last node's position. An order update of the order it
executes (same orderId, a higher orderUpdateId: the server sends a route certain to follow ahead) is
stitched on, and finishes with it.
"""

from __future__ import annotations

import time
from typing import Any

import orjson

from vda5050.codec import encode
from vda5050.models import (
    AgvClass,
    AgvGeometry,
    AgvKinematic,
    ConnectionContent,
    ConnectionState,
    FactsheetContent,
    Header,
    LoadSpecification,
    LocalizationType,
    MaxArrayLens,
    MaxStringLens,
    NavigationType,
    PhysicalParameters,
    ProtocolFeatures,
    ProtocolLimits,
    Timing,
    TypeSpecification,
)

VERSION = "2.0.0"
FINISHED, WAITING, FAILED = "FINISHED", "WAITING", "FAILED"
CANCEL_ORDER, FACTSHEET_REQUEST = "cancelOrder", "factsheetRequest"
INSTANT_ACTIONS_KEYS = ("actions", "instantActions")  # 2.x name, and the 1.1 name the reference sends
DEFAULT_MAP = "map"
# Constant parts of every state, shared by all robots (never mutated).
BATTERY = {"batteryCharge": 100.0, "charging": False}
SAFETY = {"eStop": "NONE", "fieldViolation": False}


class OrderError(ValueError):
    """An order without the fields a robot needs (orderId, nodes with nodeId and sequenceId)."""


class FakeRobot:
    """One robot's protocol state; the caller publishes what it returns and decides when orders finish."""

    __slots__ = ("_body", "_legs", "_order", "_state", "header_ids", "manufacturer", "serial", "topic")

    def __init__(self, *, serial: str, manufacturer: str, topic_prefix: str, x: float, y: float) -> None:
        self.serial = serial
        self.manufacturer = manufacturer
        self.topic = f"{topic_prefix}/{serial}/"  # + "state", "order", ...
        self.header_ids = {"state": 0, "connection": 0, "factsheet": 0}
        self._order: dict[str, Any] | None = None  # the order being executed, until it finishes
        self._legs = 0  # the messages (order and updates stitched on) it consists of
        self._state: dict[str, Any] = {
            "version": VERSION,
            "manufacturer": manufacturer,
            "serialNumber": serial,
            "orderId": "",
            "orderUpdateId": 0,
            "lastNodeId": "",
            "lastNodeSequenceId": 0,
            "nodeStates": [],
            "edgeStates": [],
            "driving": False,
            "actionStates": [],
            "agvPosition": _position(x, y, 0.0, DEFAULT_MAP),
            "batteryState": BATTERY,
            "operatingMode": "AUTOMATIC",
            "errors": [],
            "safetyState": SAFETY,
        }
        self._body = b""
        self._serialize()

    # --- messages -------------------------------------------------------------------------------------

    def state(self, timestamp: bytes) -> bytes:
        """The current state with the next headerId; ``timestamp`` is ISO 8601 UTC (see ``utc_now``)."""
        header_id = self.header_ids["state"]
        self.header_ids["state"] = header_id + 1
        return b'{"headerId":%d,"timestamp":"%b",%b' % (header_id, timestamp, self._body)

    def connection(self, connection_state: ConnectionState) -> bytes:
        return encode(ConnectionContent(connection_state=connection_state), self._header("connection"))

    def factsheet(self) -> bytes:
        return encode(MINIMAL_FACTSHEET, self._header("factsheet"))

    def _header(self, topic: str) -> Header:
        header_id = self.header_ids[topic]
        self.header_ids[topic] = header_id + 1
        return Header(
            header_id=header_id,
            timestamp=utc_now().decode(),
            version=VERSION,
            manufacturer=self.manufacturer,
            serial_number=self.serial,
        )

    # --- orders and instant actions ---------------------------------------------------------------------

    @property
    def order_id(self) -> str | None:
        """The order being executed (accepted, not yet finished)."""
        return self._order["orderId"] if self._order is not None else None

    def accept(self, order: dict[str, Any]) -> bool:
        """Take an order: at its first node, every other node and edge still ahead. False for a resend."""
        try:
            order_id, update_id, nodes = order["orderId"], order.get("orderUpdateId", 0), order["nodes"]
            first, edges = nodes[0], order.get("edges", [])
            node_states = [_node_state(node) for node in nodes[1:]]
            edge_states = [_edge_state(edge) for edge in edges]
            actions = [action for node in nodes for action in node.get("actions", ())]
            action_states = [_action_state(action, WAITING) for action in actions]
            first_id, first_sequence = first["nodeId"], first["sequenceId"]
        except (KeyError, IndexError, TypeError) as exc:
            raise OrderError(f"order lacks {exc}") from exc
        state = self._state
        if state["orderId"] == order_id and state["orderUpdateId"] == update_id:
            return False
        if self._order is not None and state["orderId"] == order_id and update_id > state["orderUpdateId"]:
            self._stitch(order, update_id, node_states, edge_states, action_states)
            return True
        self._order = order
        self._legs = 1
        state.update(
            orderId=order_id,
            orderUpdateId=update_id,
            lastNodeId=first_id,
            lastNodeSequenceId=first_sequence,
            nodeStates=node_states,
            edgeStates=edge_states,
            actionStates=action_states,
            driving=bool(node_states),
        )
        self._serialize()
        return True

    def _stitch(
        self,
        update: dict[str, Any],
        update_id: int,
        node_states: list[dict[str, Any]],
        edge_states: list[dict[str, Any]],
        action_states: list[dict[str, Any]],
    ) -> None:
        """Extend the order being executed with an update that starts at its last node."""
        assert self._order is not None
        self._order = {**self._order, "nodes": self._order["nodes"] + update["nodes"][1:]}
        self._legs += 1
        state = self._state
        state.update(
            orderUpdateId=update_id,
            nodeStates=state["nodeStates"] + node_states,
            edgeStates=state["edgeStates"] + edge_states,
            actionStates=state["actionStates"] + action_states,
        )
        self._serialize()

    def finish(self) -> int:
        """The order is done: at its last node, nothing left, every action FINISHED. Returns how many
        messages it consisted of (the order and the updates stitched on)."""
        assert self._order is not None, "finish() without an accepted order"
        last = self._order["nodes"][-1]
        state = self._state
        state.update(
            lastNodeId=last["nodeId"],
            lastNodeSequenceId=last["sequenceId"],
            nodeStates=[],
            edgeStates=[],
            driving=False,
            actionStates=[{**action, "actionStatus": FINISHED} for action in state["actionStates"]],
        )
        position = last.get("nodePosition")
        if position:
            current = state["agvPosition"]
            state["agvPosition"] = _position(
                position.get("x", current["x"]),
                position.get("y", current["y"]),
                position.get("theta", current["theta"]),
                position.get("mapId") or current["mapId"],
            )
        self._order = None
        self._serialize()
        return self._legs

    def instant_actions(self, message: dict[str, Any]) -> list[str]:
        """Run the instant actions (all FINISHED at once); returns their types, for the caller to act on."""
        actions = next((message[key] for key in INSTANT_ACTIONS_KEYS if key in message), None)
        if not isinstance(actions, list) or not all(
            isinstance(action, dict) and "actionId" in action for action in actions
        ):
            raise OrderError("instantActions lacks its actions array or an actionId")
        state = self._state
        known = {action["actionId"] for action in state["actionStates"]}
        types = []
        for action in actions:
            if action.get("actionType") == CANCEL_ORDER:
                self._cancel()
            if action.get("actionId") not in known:
                state["actionStates"].append(_action_state(action, FINISHED))
            types.append(action.get("actionType", ""))
        self._serialize()
        return types

    def _cancel(self) -> None:
        """Stop where it is: nothing left to drive, unfinished order actions FAILED, orderId kept."""
        self._order = None
        state = self._state
        state.update(
            nodeStates=[],
            edgeStates=[],
            driving=False,
            actionStates=[
                {**action, "actionStatus": FAILED} if action["actionStatus"] == WAITING else action
                for action in state["actionStates"]
            ],
        )

    def _serialize(self) -> None:
        self._body = orjson.dumps(self._state)[1:]  # without "{": the header goes in front


def _position(x: float, y: float, theta: float, map_id: str) -> dict[str, Any]:
    return {"x": x, "y": y, "theta": theta, "mapId": map_id, "positionInitialized": True}


def _node_state(node: dict[str, Any]) -> dict[str, Any]:
    return {
        "nodeId": node["nodeId"],
        "sequenceId": node["sequenceId"],
        "released": node.get("released", True),
    }


def _edge_state(edge: dict[str, Any]) -> dict[str, Any]:
    return {
        "edgeId": edge["edgeId"],
        "sequenceId": edge["sequenceId"],
        "released": edge.get("released", True),
    }


def _action_state(action: dict[str, Any], status: str) -> dict[str, Any]:
    return {
        "actionId": action["actionId"],
        "actionType": action.get("actionType", ""),
        "actionStatus": status,
    }


_second_cache: tuple[int, bytes] = (-1, b"")


def utc_now() -> bytes:
    """``YYYY-MM-DDTHH:MM:SS.fffZ`` for now; the seconds part is formatted once per second."""
    global _second_cache
    now = time.time()
    second = int(now)
    if _second_cache[0] != second:
        _second_cache = (second, time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(second)).encode())
    return b"%b.%03dZ" % (_second_cache[1], int((now - second) * 1000))


# The smallest factsheet the 2.0.0 schema accepts; the benchmark's robots have no actions of their own.
MINIMAL_FACTSHEET = FactsheetContent(
    type_specification=TypeSpecification(
        series_name="Mission Dispatch benchmark robot",
        agv_kinematic=AgvKinematic.OMNI,
        agv_class=AgvClass.CARRIER,
        max_load_mass=0.0,
        localization_types=[LocalizationType.NATURAL],
        navigation_types=[NavigationType.AUTONOMOUS],
    ),
    physical_parameters=PhysicalParameters(
        speed_min=0.0,
        speed_max=1.0,
        acceleration_max=1.0,
        deceleration_max=1.0,
        height_min=0.3,
        height_max=0.3,
        width=0.6,
        length=0.8,
    ),
    protocol_limits=ProtocolLimits(
        max_string_lens=MaxStringLens(),
        max_array_lens=MaxArrayLens(),
        timing=Timing(min_order_interval=0.0, min_state_interval=0.0),
    ),
    protocol_features=ProtocolFeatures(optional_parameters=[], agv_actions=[]),
    agv_geometry=AgvGeometry(),
    load_specification=LoadSpecification(),
)
