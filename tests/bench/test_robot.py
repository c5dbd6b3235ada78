"""The benchmark's fake robot: hand-built states must be valid VDA 5050 2.0.0 at every step."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import orjson
import pytest

from bench.robot import FakeRobot, OrderError, utc_now
from tests.vda5050.schemas import validate_message
from vda5050 import orders
from vda5050.codec import encode, header_for, parse_factsheet, parse_state
from vda5050.models import ConnectionState
from vda5050.topics import RobotAddress

ADDRESS = RobotAddress("uagv", "RobotCompany", "bench-x-0")


def robot() -> FakeRobot:
    return FakeRobot(
        serial="bench-x-0", manufacturer="RobotCompany", topic_prefix="uagv/v2/RobotCompany", x=2, y=4
    )


def wire(content: Any) -> dict[str, Any]:
    """A message as the server puts it on the wire."""
    return orjson.loads(encode(content, header_for(ADDRESS, header_id=0, at=datetime.now(UTC))))


def route_order(node_index: int, *points: tuple[float, float]) -> dict[str, Any]:
    waypoints = [orders.Waypoint(x, y, 0.0, "map") for x, y in points]
    start = orders.Pose(2.0, 4.0, 0.0, "map")
    return wire(
        orders.route_order(mission="m", node_index=node_index, attempt=0, start=start, waypoints=waypoints)
    )


def state(fake: FakeRobot) -> dict[str, Any]:
    message = orjson.loads(fake.state(utc_now()))
    validate_message("state", "2.0.0", message)
    parse_state(orjson.dumps(message))
    return message


def test_idle_robot_reports_its_home_and_counts_header_ids() -> None:
    fake = robot()
    first, second = state(fake), state(fake)
    assert (first["headerId"], second["headerId"]) == (0, 1)
    assert first["agvPosition"] == {"x": 2, "y": 4, "theta": 0.0, "mapId": "map", "positionInitialized": True}
    assert (first["orderId"], first["nodeStates"], first["actionStates"]) == ("", [], [])


def test_accepted_order_shows_the_rest_of_the_route_then_finishes_at_its_last_node() -> None:
    fake = robot()
    order = route_order(1, (3, 4), (3, 5))
    assert fake.accept(order)
    accepted = state(fake)
    assert (accepted["orderId"], accepted["lastNodeSequenceId"], accepted["driving"]) == ("m-n1-r0", 0, True)
    assert [node["sequenceId"] for node in accepted["nodeStates"]] == [2, 4]
    assert [edge["sequenceId"] for edge in accepted["edgeStates"]] == [1, 3]

    fake.finish()
    done = state(fake)
    assert (done["lastNodeId"], done["lastNodeSequenceId"]) == ("m-n1-r0-s4", 4)
    assert (done["nodeStates"], done["edgeStates"], done["driving"]) == ([], [], False)
    assert (done["agvPosition"]["x"], done["agvPosition"]["y"]) == (3, 5)
    assert fake.order_id is None


def test_a_resent_order_is_ignored_and_a_new_one_replaces_the_finished_one() -> None:
    fake = robot()
    first = route_order(1, (3, 4))
    assert fake.accept(first)
    fake.finish()
    assert not fake.accept(first)
    assert fake.accept(route_order(2, (3, 5)))
    assert state(fake)["orderId"] == "m-n2-r0"


def test_an_update_of_the_running_order_is_stitched_on_and_finishes_with_it() -> None:
    fake = robot()
    first = route_order(1, (3, 4))
    content = orders.route_order(
        mission="m",
        node_index=1,
        attempt=0,
        start=orders.Pose(2.0, 4.0, 0.0, "map"),
        waypoints=[orders.Waypoint(3, 4, 0.0, "map")],
    )
    update = wire(orders.order_update(content, waypoints=[orders.Waypoint(3, 6, 0.0, "map")], ids="m-n2-r0"))
    assert fake.accept(first) and fake.accept(update)
    assert not fake.accept(update)
    both = state(fake)
    assert (both["orderUpdateId"], both["lastNodeSequenceId"]) == (1, 0)
    assert [node["sequenceId"] for node in both["nodeStates"]] == [2, 4]
    assert [edge["sequenceId"] for edge in both["edgeStates"]] == [1, 3]

    assert fake.finish() == 2
    done = state(fake)
    assert (done["lastNodeId"], done["lastNodeSequenceId"], done["agvPosition"]["y"]) == ("m-n2-r0-s4", 4, 6)


def test_order_actions_wait_and_finish_with_the_order() -> None:
    fake = robot()
    order = wire(
        orders.action_order(
            mission="m",
            node_index=1,
            attempt=0,
            start=orders.Pose(2, 4, 0, "map"),
            action_type="dummy_action",
            parameters={"time": 1},
        )
    )
    fake.accept(order)
    assert [a["actionStatus"] for a in state(fake)["actionStates"]] == ["WAITING"]
    fake.finish()
    assert [a["actionStatus"] for a in state(fake)["actionStates"]] == ["FINISHED"]


def test_cancel_order_stops_the_order_and_instant_actions_finish() -> None:
    fake = robot()
    fake.accept(route_order(1, (3, 4)))
    cancel = wire(
        orders.instant_actions([orders.cancel_order("c1"), orders.instant_action("factsheetRequest", "f1")])
    )
    assert fake.instant_actions(cancel) == ["cancelOrder", "factsheetRequest"]
    canceled = state(fake)
    assert (canceled["nodeStates"], canceled["edgeStates"], canceled["orderId"]) == ([], [], "m-n1-r0")
    assert {a["actionId"]: a["actionStatus"] for a in canceled["actionStates"]} == {
        "c1": "FINISHED",
        "f1": "FINISHED",
    }
    assert fake.order_id is None


def test_the_reference_instant_actions_key_is_understood() -> None:
    fake = robot()
    fake.instant_actions(
        {"instantActions": [{"actionId": "a", "actionType": "stateRequest", "blockingType": "HARD"}]}
    )
    assert state(fake)["actionStates"][0]["actionId"] == "a"


@pytest.mark.parametrize(
    "order", [{}, {"orderId": "o", "orderUpdateId": 0, "nodes": []}, {"orderId": "o", "nodes": [{}]}]
)
def test_an_order_without_what_a_robot_needs_is_refused(order: dict[str, Any]) -> None:
    with pytest.raises(OrderError):
        robot().accept(order)


def test_connection_and_factsheet_are_valid() -> None:
    fake = robot()
    online = orjson.loads(fake.connection(ConnectionState.ONLINE))
    validate_message("connection", "2.0.0", online)
    factsheet = fake.factsheet()
    validate_message("factsheet", "2.0.0", orjson.loads(factsheet))
    assert parse_factsheet(factsheet).serial_number == "bench-x-0"
