"""Simulated robots' zones (3.0): zone sets from the zoneSet topic, enabled and deleted by instant actions,
reported in `zoneSets`; and ACCESS requests for RELEASE zones, waited on at the last node before the zone
until fleet control grants them on `responses`. Every message checked against its version's schema."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from simulator.factsheet import factsheet_content
from tests.simulator.conftest import RobotHarness, route
from vda5050.codec import encode, header_for
from vda5050.models import (
    Action,
    ActionStatus,
    ActionType,
    InstantActionsContent,
    MapStatus,
    Response,
    ResponsesContent,
    StateContent,
)
from vda5050.orders import instant_action
from vda5050.topics import Topic, topic_for
from vda5050.zones import ZONE_SET_ID, zone_set_message

SPEC_3 = "carter30,0,0,0,map,0,20,RobotCompany,carter30,CARRIER,3.0.0"
# A narrow aisle across the robot's way along y = 0, from x = 2 to x = 3.
AISLE = [{"x": 2.0, "y": -1.0}, {"x": 3.0, "y": -1.0}, {"x": 3.0, "y": 1.0}, {"x": 2.0, "y": 1.0}]
RELEASE = {"zone_id": "aisle", "zone_type": "RELEASE", "vertices": AISLE, "release_loss_behavior": "STOP"}


def send_zone_set(h: RobotHarness, zone_set_id: str = "floor1-v1", map_id: str = "map") -> None:
    content = zone_set_message(
        zone_set_id=zone_set_id,
        map_id=map_id,
        description="",
        zones=[
            RELEASE,
            {"zone_id": "slow", "zone_type": "SPEED_LIMIT", "vertices": AISLE, "maximum_speed": 0.5},
        ],
    )
    h.record(h.robot.receive(Topic.ZONE_SET, encode(content, h.header()), h.now))


def respond(h: RobotHarness, request_id: str, grant_type: str) -> None:
    content = ResponsesContent(responses=[Response(request_id=request_id, grant_type=grant_type)])
    h.record(h.robot.receive(Topic.RESPONSES, encode(content, h.header()), h.now))


def zone_sets(h: RobotHarness) -> list[tuple[str, MapStatus]]:
    return [(z.zone_set_id, z.zone_set_status) for z in h.state.zone_sets or ()]


def requests(state: StateContent) -> list[tuple[str, str, str]]:
    return [(r.zone_id, r.zone_set_id, r.request_status) for r in state.zone_requests or ()]


def factsheet_actions(h: RobotHarness, version: str) -> set[str]:
    return {
        a.action_type for a in factsheet_content(h.config, h.settings, version).protocol_features.agv_actions
    }


def instant_status(h: RobotHarness, action_id: str) -> ActionStatus:
    return next(a.action_status for a in h.state.instant_action_states or () if a.action_id == action_id)


def zone_action(action_type: str, action_id: str, zone_set_id: str) -> Action:
    return instant_action(action_type, action_id, {ZONE_SET_ID: zone_set_id})


@pytest.fixture
def h() -> RobotHarness:
    return RobotHarness(SPEC_3, tick_period=0.25)


@pytest.fixture
def enabled(h: RobotHarness) -> RobotHarness:
    send_zone_set(h)
    h.send_actions(zone_action(ActionType.ENABLE_ZONE_SET, "e1", "floor1-v1"))
    return h


# --- zone sets ----------------------------------------------------------------------------------------


def test_a_zone_set_arrives_disabled_is_enabled_and_deleted(h: RobotHarness) -> None:
    assert zone_sets(h) == []
    send_zone_set(h)
    assert zone_sets(h) == [("floor1-v1", MapStatus.DISABLED)]

    h.send_actions(zone_action(ActionType.ENABLE_ZONE_SET, "e1", "floor1-v1"))
    assert (zone_sets(h), instant_status(h, "e1")) == (
        [("floor1-v1", MapStatus.ENABLED)],
        ActionStatus.FINISHED,
    )

    h.send_actions(zone_action(ActionType.DELETE_ZONE_SET, "x1", "floor1-v1"))
    assert (zone_sets(h), instant_status(h, "x1")) == ([], ActionStatus.FINISHED)


def test_enabling_a_set_disables_the_other_sets_of_its_map_only(h: RobotHarness) -> None:
    for zone_set_id, map_id in (("a", "map"), ("b", "map"), ("c", "hall")):
        send_zone_set(h, zone_set_id, map_id)
    h.send_actions(
        zone_action(ActionType.ENABLE_ZONE_SET, "e1", "a"), zone_action(ActionType.ENABLE_ZONE_SET, "e2", "c")
    )

    h.send_actions(zone_action(ActionType.ENABLE_ZONE_SET, "e3", "b"))

    assert sorted(zone_sets(h)) == [
        ("a", MapStatus.DISABLED),
        ("b", MapStatus.ENABLED),
        ("c", MapStatus.ENABLED),
    ]


def test_a_duplicate_set_is_not_taken_and_an_unknown_one_cannot_be_enabled(h: RobotHarness) -> None:
    send_zone_set(h)
    send_zone_set(h)
    assert [e.error_type for e in h.state.errors] == ["DUPLICATE_ZONE_SET"]

    h.send_actions(zone_action(ActionType.ENABLE_ZONE_SET, "e9", "floor9"))

    assert instant_status(h, "e9") == ActionStatus.FAILED


def test_a_2_x_robot_takes_no_zone_sets() -> None:
    h = RobotHarness("old,0,0,0,map,0,20,RobotCompany,old,CARRIER,2.1.0")
    assert h.robot.subscriptions() == [h.robot.topic(Topic.ORDER), h.robot.topic(Topic.INSTANT_ACTIONS)]
    assert h.robot.receive(Topic.ZONE_SET, b"{}", h.now) == []
    assert h.state.zone_sets is None
    assert ActionType.ENABLE_ZONE_SET not in factsheet_actions(h, "2.1.0")


def test_a_3_0_robot_lists_release_zones_and_the_zone_set_actions_in_its_factsheet(h: RobotHarness) -> None:
    factsheet = factsheet_content(h.config, h.settings, "3.0.0")
    assert factsheet.type_specification.supported_zones == ["RELEASE"]
    assert {ActionType.ENABLE_ZONE_SET, ActionType.DELETE_ZONE_SET} <= factsheet_actions(h, "3.0.0")


# --- access to RELEASE zones ------------------------------------------------------------------------------


def test_the_robot_waits_at_the_last_node_before_the_zone_until_granted_then_drops_the_request(
    enabled: RobotHarness,
) -> None:
    h = enabled
    h.send_order(route((1.0, 0.0), (5.0, 0.0)))

    waiting = h.run_until(lambda s: bool(s.zone_requests) and not s.driving)
    assert requests(waiting) == [("aisle", "floor1-v1", "REQUESTED")]
    assert waiting.agv_position.x == pytest.approx(1.0)
    h.run(3.0)
    assert h.state.agv_position.x == pytest.approx(1.0)  # still waiting

    [request] = h.state.zone_requests
    respond(h, request.request_id, "GRANTED")
    assert requests(h.state) == [("aisle", "floor1-v1", "GRANTED")]

    done = h.run_until(lambda s: not s.node_states)
    assert done.agv_position.x == pytest.approx(5.0)
    assert done.zone_requests == []
    # The request was held while the robot was inside, and only then.
    for state in h.states():
        if state.agv_position is not None and 2.0 <= state.agv_position.x <= 3.0:
            assert requests(state) == [("aisle", "floor1-v1", "GRANTED")]


@pytest.mark.parametrize("answer", ["QUEUED", "REJECTED", "REVOKED"])
def test_queued_rejected_or_revoked_before_entry_keep_the_robot_waiting(
    enabled: RobotHarness, answer: str
) -> None:
    h = enabled
    h.send_order(route((1.0, 0.0), (5.0, 0.0)))
    h.run_until(lambda s: bool(s.zone_requests) and not s.driving)
    [request] = h.state.zone_requests
    if answer == "REVOKED":
        respond(h, request.request_id, "GRANTED")
        h.tick()  # sets off towards the zone

    respond(h, request.request_id, answer)
    h.run(3.0)

    assert requests(h.state) == [("aisle", "floor1-v1", "REQUESTED")]
    assert h.state.agv_position.x < 2.0
    respond(h, request.request_id, "GRANTED")
    assert h.run_until(lambda s: not s.node_states).agv_position.x == pytest.approx(5.0)


def test_a_route_that_misses_the_zone_or_a_disabled_set_asks_nothing(h: RobotHarness) -> None:
    send_zone_set(h)  # disabled
    h.send_order(route((1.0, 0.0), (5.0, 0.0)))
    assert h.run_until(lambda s: not s.node_states).zone_requests == []

    h.send_actions(zone_action(ActionType.ENABLE_ZONE_SET, "e1", "floor1-v1"))
    h.send_order(route((5.0, 5.0), start=(5.0, 0.0), mission="m2"))
    assert h.run_until(lambda s: not s.node_states).zone_requests == []


def test_a_request_never_entered_is_dropped_when_the_order_is_cancelled(enabled: RobotHarness) -> None:
    h = enabled
    h.send_order(route((1.0, 0.0), (5.0, 0.0)))
    h.run_until(lambda s: bool(s.zone_requests) and not s.driving)

    h.send_actions(instant_action(ActionType.CANCEL_ORDER, "c1"))
    h.tick()

    assert h.state.zone_requests == []


# --- over the real broker, with a fake fleet control ------------------------------------------------------


def test_over_mqtt_a_fake_fleet_control_distributes_a_zone_set_and_grants_the_robot_its_zone(
    start_simulator, probe
) -> None:
    simulator = start_simulator("--robots", SPEC_3, "--speed", "10", "--tick_period", "0.05")
    address = simulator.address("carter30", version="3.0.0")
    headers = iter(range(1000))

    def publish(topic: Topic, content) -> None:
        header = header_for(address, header_id=next(headers), at=datetime.now(UTC))
        probe.publish(topic_for(address, topic), encode(content, header))

    def state_where(condition) -> dict:
        return probe.wait_for(lambda r: r.kind == Topic.STATE and condition(r.body), "a state").body

    state_where(lambda s: s["zoneSets"] == [])
    publish(Topic.ZONE_SET, zone_set_message(zone_set_id="z1", map_id="map", description="", zones=[RELEASE]))
    state_where(lambda s: s["zoneSets"] == [{"zoneSetId": "z1", "mapId": "map", "zoneSetStatus": "DISABLED"}])
    publish(Topic.INSTANT_ACTIONS, InstantActionsContent(actions=[zone_action("enableZoneSet", "e1", "z1")]))
    state_where(lambda s: s["zoneSets"] == [{"zoneSetId": "z1", "mapId": "map", "zoneSetStatus": "ENABLED"}])

    publish(Topic.ORDER, route((1.0, 0.0), (5.0, 0.0)))
    waiting = state_where(lambda s: s["zoneRequests"] and not s["driving"])
    [request] = waiting["zoneRequests"]
    assert (request["zoneId"], request["requestType"], request["requestStatus"]) == (
        "aisle",
        "ACCESS",
        "REQUESTED",
    )
    assert waiting["mobileRobotPosition"]["x"] == pytest.approx(1.0)

    publish(
        Topic.RESPONSES,
        ResponsesContent(responses=[Response(request_id=request["requestId"], grant_type="GRANTED")]),
    )

    done = state_where(
        lambda s: not s["nodeStates"] and not s["driving"] and s["mobileRobotPosition"]["x"] > 4.9
    )
    assert done["zoneRequests"] == []
