"""Simulated 3.0.0 robots (per robot: the spec's vda_version) and robots that behave like a real stack
(the spec's stack, e.g. vda-5050-lib 1.4.0), every message checked against its version's schema."""

from __future__ import annotations

import orjson

from simulator.config import Stack, parse_robot_spec
from tests.simulator.conftest import RobotHarness, keep_busy, route
from vda5050.codec import encode
from vda5050.models import ActionStatus, BlockingType, InstantActionsContent
from vda5050.orders import Waypoint, cancel_order, instant_action, order_update
from vda5050.topics import Topic

SPEC_3 = "carter03,0,0,0,map,0,20,RobotCompany,carter03,CARRIER,3.0.0"
SPEC_LIB = "npm01,0,0,0,map,0,20,RobotCompany,npm01,CARRIER,2.0.0,vda-5050-lib-1.4"
SPEC_SDK = "sdk01,0,0,0,map,0,20,RobotCompany,sdk01,CARRIER,2.1.0,vda5050-sdk-0.2"


def test_a_robot_spec_names_its_version_and_stack() -> None:
    config = parse_robot_spec(SPEC_LIB)

    assert (config.vda_version, config.stack) == ("2.0.0", Stack.VDA_5050_LIB_1_4)
    assert parse_robot_spec("a,0,0").vda_version == ""


def test_every_message_of_a_busy_3_0_robot_is_valid_3_0() -> None:
    h = RobotHarness(SPEC_3, version="2.0.0", visualization_period=0.5)  # the spec's version wins
    keep_busy(h)

    assert {m.kind for m in h.sent} == {Topic.CONNECTION, Topic.FACTSHEET, Topic.STATE, Topic.VISUALIZATION}
    assert {orjson.loads(m.payload)["version"] for m in h.sent} == {"3.0.0"}
    assert {m.topic.split("/")[1] for m in h.sent} == {"v3"}
    last_state = orjson.loads(next(m.payload for m in reversed(h.sent) if m.kind == Topic.STATE))
    assert {"mobileRobotPosition", "powerSupply", "instantActionStates"} <= last_state.keys()
    assert {a["actionId"] for a in last_state["instantActionStates"]} == {"fr", "c", "u"}
    assert {a["actionId"] for a in last_state["actionStates"]} >= {"p", "f"}
    assert "VALIDATION_FAILURE" in {e["errorType"] for e in last_state["errors"]}  # 3.0's name, for b"{}"


def test_a_3_0_robot_rejects_blocking_instant_actions() -> None:
    h = RobotHarness(SPEC_3)
    body = orjson.loads(encode(InstantActionsContent(actions=[cancel_order("c")]), h.header()))
    body["actions"][0]["blockingType"] = BlockingType.HARD

    h.record(h.robot.receive(Topic.INSTANT_ACTIONS, orjson.dumps(body), h.now))

    [error] = h.state.errors
    assert (error.error_type, error.error_description) == (
        "VALIDATION_FAILURE",
        "actions[0].blockingType must be NONE in VDA 5050 3.0",
    )
    assert h.state.instant_action_states == []


def test_a_vda_5050_lib_1_4_robot_rejects_the_actions_key_as_the_library_does() -> None:
    h = RobotHarness(SPEC_LIB)

    h.send_actions(instant_action("stateRequest", "s1"))

    [error] = h.state.errors
    assert error.error_type == "validationError"
    assert error.error_description is not None and "#/instantActions" in error.error_description
    assert [(r.reference_key, r.reference_value) for r in error.error_references or ()] == [
        ("topic", "instantActions"),
        ("headerId", "0"),
    ]
    assert h.state.action_states == []


def test_a_vda_5050_lib_1_4_robot_runs_instant_actions_under_the_legacy_key() -> None:
    h = RobotHarness(SPEC_LIB)
    payload = encode(
        InstantActionsContent(actions=[instant_action("stateRequest", "s1")]),
        h.header(),
        instant_actions_key="instantActions",
    )

    h.record(h.robot.receive(Topic.INSTANT_ACTIONS, payload, h.now))

    assert [(a.action_id, a.action_status) for a in h.state.action_states] == [("s1", ActionStatus.FINISHED)]
    assert h.state.errors == []


def test_a_vda_5050_lib_1_4_robot_refuses_a_cancel_without_an_order_by_an_error_only() -> None:
    h = RobotHarness(SPEC_LIB)
    payload = encode(
        InstantActionsContent(actions=[cancel_order("c1")]), h.header(), instant_actions_key="instantActions"
    )

    h.record(h.robot.receive(Topic.INSTANT_ACTIONS, payload, h.now))

    assert h.state.action_states == []
    [error] = h.state.errors
    assert error.error_type == "noOrderToCancel"
    assert ("actionId", "c1") in [(r.reference_key, r.reference_value) for r in error.error_references or ()]


def test_a_vda5050_sdk_0_2_robot_takes_an_update_and_stands_still_at_the_end_of_its_base() -> None:
    h = RobotHarness(SPEC_SDK)
    first = route((1, 0), (2, 0))
    h.send_order(first)
    h.send_order(order_update(first, waypoints=[Waypoint(2, 1, 0.0, "map")], ids="m1-n1-r0"))
    assert h.state.order_update_id == 1 and [n.sequence_id for n in h.state.node_states] == [2, 4, 6]

    h.run(20)

    state = h.state
    assert (state.last_node_sequence_id, state.agv_position.x, state.agv_position.y) == (4, 2.0, 0.0)
    assert not state.driving and not state.errors and [n.sequence_id for n in state.node_states] == [6]

    h.send_actions(cancel_order("c"))  # what ends it: the rest as a new order is driven
    assert h.action_state("c").action_status == ActionStatus.FINISHED and not h.state.node_states
    h.send_order(route((2, 1), start=(2, 0), mission="m2"))
    assert h.run_until(lambda s: s.last_node_sequence_id == 2 and not s.driving).agv_position.y == 1.0
