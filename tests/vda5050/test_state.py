from __future__ import annotations

from typing import Any

import pytest

from tests.vda5050.samples import sample_header
from vda5050.models import (
    ActionState,
    ActionStatus,
    AgvPosition,
    BatteryState,
    EdgeState,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    NodeState,
    OperatingMode,
    SafetyState,
    State,
)
from vda5050.orders import Pose
from vda5050.state import (
    Telemetry,
    action_status,
    errors_referencing,
    fatal_errors,
    is_idle,
    last_node_reached,
    may_receive_orders,
    order_accepted,
    order_rejection,
    robot_telemetry,
    warnings,
)


def make_state(**fields: Any) -> State:
    """An idle robot that last ran order ``o``/update 1, with ``fields`` overriding."""
    defaults: dict[str, Any] = {
        "order_id": "o",
        "order_update_id": 1,
        "last_node_id": "o-s2",
        "last_node_sequence_id": 2,
        "driving": False,
        "operating_mode": OperatingMode.AUTOMATIC,
        "node_states": [],
        "edge_states": [],
        "action_states": [],
        "battery_state": BatteryState(battery_charge=42.5, charging=True),
        "errors": [],
        "safety_state": SafetyState(e_stop=EStop.NONE, field_violation=False),
    }
    return State(**sample_header("2.0.0").model_dump(), **(defaults | fields))


def error(error_type: str, level: ErrorLevel = ErrorLevel.WARNING, **references: str) -> Error:
    return Error(
        error_type=error_type,
        error_level=level,
        error_references=[ErrorReference(reference_key=k, reference_value=v) for k, v in references.items()]
        or None,
    )


def node_state(sequence_id: int) -> NodeState:
    return NodeState(node_id=f"o-s{sequence_id}", sequence_id=sequence_id, released=True)


def edge_state(sequence_id: int) -> EdgeState:
    return EdgeState(edge_id=f"o-e{sequence_id}", sequence_id=sequence_id, released=True)


def action(action_id: str, status: ActionStatus) -> ActionState:
    return ActionState(action_id=action_id, action_status=status)


@pytest.mark.parametrize(
    ("state_order", "state_update", "order", "update", "accepted"),
    [
        ("o", 1, "o", 1, True),
        ("o", 2, "o", 1, True),
        ("o", 0, "o", 1, False),
        ("other", 5, "o", 1, False),
        ("", 0, "o", 0, False),
    ],
)
def test_order_accepted(state_order: str, state_update: int, order: str, update: int, accepted: bool) -> None:
    state = make_state(order_id=state_order, order_update_id=state_update)

    assert order_accepted(state, order, update) is accepted


@pytest.mark.parametrize(
    ("errors", "state_order", "expected_type"),
    [
        ([error("validationError", orderId="new", orderUpdateId="0")], "old", "validationError"),
        ([error("orderError", orderId="new")], "old", "orderError"),
        ([error("busy", order_id="new")], "old", "busy"),  # vendor type, snake_case key
        ([error("orderUpdateError", OrderID=" new ", orderUpdateId="0")], "old", "orderUpdateError"),
        ([error("orderError", orderId="new", orderUpdateId="3")], "old", None),  # another update
        ([error("orderError", orderId="older")], "old", None),
        ([error("noOrderToCancel", actionId="c1")], "old", None),
        ([error("orderError")], "old", None),
        ([error("orderError", orderId="new", orderUpdateId="0")], "new", None),  # shown as accepted
    ],
)
def test_order_rejection(errors: list[Error], state_order: str, expected_type: str | None) -> None:
    state = make_state(order_id=state_order, order_update_id=0, errors=errors)

    rejection = order_rejection(state, "new", 0)

    assert (rejection.error_type if rejection else None) == expected_type


@pytest.mark.parametrize(
    ("fields", "sequence_id", "reached"),
    [
        ({"last_node_sequence_id": 2, "node_states": [node_state(4)]}, 2, True),
        ({"last_node_sequence_id": 4, "node_states": []}, 2, True),
        ({"last_node_sequence_id": 4, "node_states": []}, 4, True),
        ({"last_node_sequence_id": 2, "node_states": [node_state(4)]}, 4, False),
        ({"last_node_sequence_id": 4, "node_states": [node_state(4)]}, 4, False),  # inconsistent: not yet
        ({"last_node_sequence_id": 4, "order_id": "other"}, 4, False),
        # the robot stands on the target but has not reported reaching it
        (
            {
                "last_node_sequence_id": 2,
                "node_states": [node_state(4)],
                "agv_position": AgvPosition(x=3, y=0, theta=0, map_id="m", position_initialized=True),
            },
            4,
            False,
        ),
    ],
)
def test_last_node_reached(fields: dict[str, Any], sequence_id: int, reached: bool) -> None:
    assert last_node_reached(make_state(**fields), "o", sequence_id) is reached


def test_action_status_is_found_by_id_not_position() -> None:
    state = make_state(
        action_states=[
            action("instant-1", ActionStatus.FINISHED),
            action("o-a0", ActionStatus.FAILED),
            action("o-a1", ActionStatus.PAUSED),
        ]
    )

    assert action_status(state, "o-a0") == ActionStatus.FAILED
    assert action_status(state, "o-a1") == ActionStatus.PAUSED
    assert action_status(state, "instant-1") == ActionStatus.FINISHED
    assert action_status(state, "missing") is None


def test_errors_referencing() -> None:
    by_order = error("e1", orderId="o")
    by_node = error("e2", nodeId="o-s2")
    by_edge = error("e3", edge_id="o-e1")
    by_action = error("e4", actionId="o-a0")
    unrelated = error("e5", nodeId="x-s2")
    state = make_state(errors=[by_order, by_node, by_edge, by_action, unrelated, error("e6")])

    assert errors_referencing(state, order_id="o") == [by_order]
    assert errors_referencing(state, node_ids=["o-s2", "o-s4"], action_ids={"o-a0"}) == [by_node, by_action]
    assert errors_referencing(state, edge_ids=("o-e1",)) == [by_edge]
    assert errors_referencing(state) == []


def test_fatal_errors_and_warnings() -> None:
    fatal = error("laserDirty", ErrorLevel.FATAL)
    warning = error("maintenanceDue")
    state = make_state(errors=[warning, fatal])

    assert fatal_errors(state) == [fatal]
    assert warnings(state) == [warning]
    assert fatal_errors(make_state()) == warnings(make_state()) == []


@pytest.mark.parametrize(
    ("fields", "idle"),
    [
        ({}, True),
        ({"action_states": [action("a", ActionStatus.FINISHED), action("b", ActionStatus.FAILED)]}, True),
        ({"node_states": [node_state(4)]}, False),
        ({"edge_states": [edge_state(3)]}, False),
        ({"action_states": [action("a", ActionStatus.FINISHED), action("b", ActionStatus.WAITING)]}, False),
        ({"action_states": [action("a", ActionStatus.RUNNING)]}, False),
        ({"action_states": [action("a", ActionStatus.PAUSED)]}, False),
        ({"action_states": [action("a", ActionStatus.INITIALIZING)]}, False),
    ],
)
def test_is_idle(fields: dict[str, Any], idle: bool) -> None:
    assert is_idle(make_state(**fields)) is idle


@pytest.mark.parametrize(
    ("mode", "allowed"),
    [
        (OperatingMode.AUTOMATIC, True),
        (OperatingMode.SEMIAUTOMATIC, True),
        (OperatingMode.MANUAL, False),
        (OperatingMode.SERVICE, False),
        (OperatingMode.TEACHIN, False),
    ],
)
def test_may_receive_orders(mode: OperatingMode, allowed: bool) -> None:
    assert may_receive_orders(make_state(operating_mode=mode)) is allowed


def test_robot_telemetry_with_position() -> None:
    position = AgvPosition(x=1.5, y=-2.0, theta=0.3, map_id="floor1", position_initialized=False)
    state = make_state(agv_position=position, paused=True, driving=True)

    assert robot_telemetry(state) == Telemetry(
        pose=Pose(1.5, -2.0, 0.3, "floor1"),
        position_initialized=False,
        battery_charge=42.5,
        charging=True,
        operating_mode=OperatingMode.AUTOMATIC,
        paused=True,
        driving=True,
        manufacturer="RobotCompany",
        serial_number="carter01",
    )


def test_robot_telemetry_without_optional_fields() -> None:
    telemetry = robot_telemetry(make_state())

    assert (telemetry.pose, telemetry.position_initialized, telemetry.paused) == (None, None, None)
    assert telemetry.battery_charge == 42.5
