"""Routes without stops, end to end: the next route leaf goes to the robot as an order update of the running
order before the robot reaches the end of the first leaf, the robot drives on, and the mission's node states
still change leaf by leaf. Real bridge, worker, beat and simulator processes; each test taps the robot's
order and state topics on the broker, so orders and the robot's states are seen in the broker's order."""

from __future__ import annotations

from typing import Any

import pytest

from tests.e2e.helpers import (
    StatusRecorder,
    create_robot,
    get,
    post_mission,
    route,
    tapped,
    wait_mission,
    wait_robot,
)
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def simulated(api, simulator, unique, version: str) -> str:
    robot = unique("ahead")
    simulator(f"{robot},0,0,0,map,0,80,RobotCompany,{robot},CARRIER,{version}")
    create_robot(api, robot, vda5050={"version": version})
    wait_robot(api, robot, online=True)
    return robot


def leaves_in_order(snapshot: dict[str, Any], leaves: list[str]) -> bool:
    """Node states of a running mission as the engine leaves them: the leaves before the current one
    COMPLETED, the current one RUNNING (or PENDING, not yet started), the later ones PENDING."""
    current = snapshot["current_node"]
    states = [snapshot["node_status"][leaf]["state"] for leaf in leaves]
    return (
        all(state == "COMPLETED" for state in states[:current])
        and states[current] in ("RUNNING", "PENDING")
        and all(state == "PENDING" for state in states[current + 1 :])
    )


@pytest.mark.parametrize("version", ["2.0.0", "2.1.0", "3.0.0"])
def test_the_next_route_is_sent_ahead_before_the_robot_reaches_the_end_of_the_first(
    api, unique, simulator, version: str
) -> None:
    robot = simulated(api, simulator, unique, version)
    name = unique("m")
    leaves = ["r1", "r2", "r3"]
    with tapped(robot) as tap:
        statuses = StatusRecorder(api, name)
        post_mission(api, name, robot, [route("r1", (10, 0)), route("r2", (10, 10)), route("r3", (0, 10))])
        mission = wait_mission(api, name)
        sequence = statuses.stop()
        wait_for(lambda: any(not s["nodeStates"] and s["orderUpdateId"] == 2 for s in tap.of("state")))
        seen = tap.seen()

    assert mission["status"]["state"] == "COMPLETED"
    assert [mission["status"]["node_status"][leaf]["state"] for leaf in leaves] == ["COMPLETED"] * 3
    orders = [data for kind, data in seen if kind == "order"]
    assert len({o["orderId"] for o in orders}) == 1, "one order, extended twice"
    assert sorted({o["orderUpdateId"] for o in orders}) == [0, 1, 2]
    for update_id in (1, 2):
        previous = next(o for o in orders if o["orderUpdateId"] == update_id - 1)
        update = next(o for o in orders if o["orderUpdateId"] == update_id)
        decision_point = previous["nodes"][-1]
        assert (update["nodes"][0]["nodeId"], update["nodes"][0]["sequenceId"]) == (
            decision_point["nodeId"],
            decision_point["sequenceId"],
        )
        sent_at = next(i for i, (kind, data) in enumerate(seen) if data is update)
        arrived_at = next(
            i
            for i, (kind, data) in enumerate(seen)
            if kind == "state" and data["lastNodeSequenceId"] >= decision_point["sequenceId"]
        )
        assert sent_at < arrived_at, f"update {update_id} sent after the robot reached the end of its leaf"
        at_decision_point = seen[arrived_at][1]
        assert at_decision_point["orderUpdateId"] >= update_id
        assert at_decision_point["driving"] and at_decision_point["nodeStates"], "the robot stopped there"
    # Leaf by leaf: every status the mission showed had the leaves before the current one done, the later
    # ones not started, and the current node only went forward.
    assert all(leaves_in_order(s, leaves) for s in statuses.snapshots if s["state"] == "RUNNING")
    running = [node for state, node in sequence if state == "RUNNING"]
    assert running == sorted(running) and len(running) >= 2
    assert sequence[-1] == ("COMPLETED", 2)


def test_cancel_in_the_middle_of_an_extended_order_stops_the_robot(api, unique, simulator) -> None:
    robot = simulated(api, simulator, unique, "2.0.0")
    name = unique("m")
    with tapped(robot) as tap:
        post_mission(api, name, robot, [route("r1", (40, 0)), route("r2", (40, 40))])
        wait_for(
            lambda: any(s["orderUpdateId"] == 1 and s["driving"] for s in tap.of("state")),
            message="the robot driving the extended order",
        )

        assert api.post(f"/mission/{name}/cancel").status_code == 200

        mission = wait_mission(api, name)
        stopped = wait_for(
            lambda: next((s for s in reversed(tap.of("state")) if not s["nodeStates"]), None),
            message="the robot stopped",
        )
        seen = tap.seen()

    assert mission["status"]["state"] == "CANCELED"
    assert {leaf: mission["status"]["node_status"][leaf]["state"] for leaf in ("r1", "r2")} == {
        "r1": "CANCELED",
        "r2": "PENDING",
    }
    cancel_at = next(
        i
        for i, (kind, data) in enumerate(seen)
        if kind == "instantActions" and data["actions"][0]["actionType"] == "cancelOrder"
    )
    orders = [data for kind, data in seen if kind == "order"]
    assert sorted({o["orderUpdateId"] for o in orders}) == [0, 1]
    assert not any(kind == "order" for kind, _ in seen[cancel_at:]), "an order after cancelOrder"
    assert stopped["orderUpdateId"] == 1 and stopped["agvPosition"]["x"] < 40
    assert get(api, "robot", robot)["status"]["state"] == "IDLE"
