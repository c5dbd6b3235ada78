"""VDA 5050 3.0.0 at the wire: what we send is spelled as 3.0.0, what 3.0.0 robots send is read tolerantly.

The received samples are written as a 3.0.0 robot sends them (3.0.0 names and structure), and each is
checked against the 3.0.0 schemas first, so they cannot drift into our own shape.
"""

from __future__ import annotations

import copy
from typing import Any

import orjson
import pytest

from tests.vda5050.samples import full_order, sample_header
from tests.vda5050.schemas import validate_message
from vda5050.codec import (
    encode,
    parse_connection,
    parse_factsheet,
    parse_order,
    parse_state,
    parse_visualization,
)
from vda5050.errors import ProtocolError
from vda5050.models import (
    ActionStatus,
    AgvKinematic,
    BlockingType,
    ConnectionState,
    ErrorLevel,
    EStop,
    NavigationType,
    OperatingMode,
)
from vda5050.orders import Pose, Waypoint, cancel_order, instant_action, instant_actions, route_order
from vda5050.state import (
    action_status,
    is_idle,
    may_receive_instant_action,
    may_receive_orders,
    order_ending_errors,
)
from vda5050.topics import RobotAddress, Topic, topic_for
from vda5050.versions import SUPPORTED_VERSIONS, supported_version

HEADER_3 = {
    "headerId": 12,
    "timestamp": "2026-11-22T10:00:00.123Z",
    "version": "3.0.0",
    "manufacturer": "RobotCompany",
    "serialNumber": "carter03",
}

STATE_3: dict[str, Any] = {
    **HEADER_3,
    "orderId": "m-n1-r0",
    "orderUpdateId": 0,
    "lastNodeId": "m-n1-r0-s0",
    "lastNodeSequenceId": 0,
    "nodeStates": [{"nodeId": "m-n1-r0-s2", "sequenceId": 2, "released": True, "nodeDescriptor": "dock"}],
    "edgeStates": [{"edgeId": "m-n1-r0-e1", "sequenceId": 1, "released": True, "edgeDescriptor": "aisle"}],
    "mobileRobotPosition": {"x": 1.5, "y": -2.0, "theta": 0.5, "mapId": "map", "localized": True},
    "driving": True,
    "actionStates": [
        {
            "actionId": "m-n1-r0-a0",
            "actionType": "pick",
            "actionStatus": "WAITING",
            "actionDescriptor": "pick",
        }
    ],
    "instantActionStates": [
        {"actionId": "carter03-startPause-1", "actionType": "startPause", "actionStatus": "RUNNING"},
        {"actionId": "carter03-factsheetRequest-1", "actionStatus": "FINISHED", "actionResult": "sent"},
    ],
    "zoneActionStates": [],
    "zoneSets": [{"mapId": "map", "zoneSetId": "zs1", "zoneSetStatus": "ENABLED"}],
    "zoneRequests": [
        {
            "requestId": "r1",
            "requestType": "ACCESS",
            "zoneId": "z1",
            "zoneSetId": "zs1",
            "requestStatus": "REQUESTED",
        }
    ],
    "powerSupply": {"stateOfCharge": 77.5, "charging": False, "batteryCurrent": -3.0, "range": 900.0},
    "operatingMode": "AUTOMATIC",
    "errors": [
        {
            "errorType": "NODE_UNREACHABLE",
            "errorLevel": "CRITICAL",
            "errorReferences": [{"referenceKey": "nodeId", "referenceValue": "m-n1-r0-s2"}],
            "errorDescriptionTranslations": [{"translationKey": "de", "translationValue": "unerreichbar"}],
        },
        {"errorType": "INSTANT_ACTION_STATES_FULL", "errorLevel": "URGENT"},
    ],
    "information": [{"infoType": "user_info", "infoLevel": "INFO", "infoDescriptor": "{}"}],
    "safetyState": {"activeEmergencyStop": "NONE", "fieldViolation": False},
    "plannedPath": {"trajectory": {"controlPoints": [{"x": 0, "y": 0}, {"x": 1, "y": 0}]}},
    "someVendorField": {"anything": True},
}

FACTSHEET_3: dict[str, Any] = {
    **HEADER_3,
    "typeSpecification": {
        "seriesName": "carter",
        "mobileRobotKinematics": "DIFFERENTIAL",
        "mobileRobotClass": "CARRIER",
        "maximumLoadMass": 100,
        "localizationTypes": ["NATURAL"],
        "navigationTypes": ["FREELY_NAVIGATING"],
        "supportedZones": ["BLOCKED"],
    },
    "physicalParameters": {
        "minimumSpeed": 0.01,
        "maximumSpeed": 1.5,
        "maximumAcceleration": 0.5,
        "maximumDeceleration": 0.8,
        "minimumHeight": 0.3,
        "maximumHeight": 0.5,
        "width": 0.6,
        "length": 0.9,
    },
    "protocolLimits": {
        "maximumStringLengths": {"maximumIdLength": 64},
        "maximumArrayLengths": {"order.nodes": 50, "state.instantActionStates": 100},
        "timing": {"minimumOrderInterval": 0.5, "minimumStateInterval": 0.1},
    },
    "protocolFeatures": {
        "optionalParameters": [],
        "mobileRobotActions": [
            {
                "actionType": "cancelOrder",
                "actionScopes": ["INSTANT"],
                "pauseAllowed": False,
                "cancelAllowed": False,
                "actionResult": "canceled",
            }
        ],
    },
    "mobileRobotGeometry": {
        "envelopes2d": [
            {"envelope2dId": "base", "vertices": [{"x": 0, "y": 0}, {"x": 1, "y": 0}, {"x": 0, "y": 1}]}
        ]
    },
    "loadSpecification": {"loadSets": [{"setName": "EPAL", "loadType": "EPAL", "maximumWeight": 80}]},
    "mobileRobotConfiguration": {"versions": [{"key": "fw", "value": "1.2"}]},
}


@pytest.fixture(scope="module", autouse=True)
def _samples_are_3_0() -> None:
    validate_message("state", "3.0.0", STATE_3)
    validate_message("factsheet", "3.0.0", FACTSHEET_3)


def test_a_3_0_state_reads_into_our_shape() -> None:
    state = parse_state(orjson.dumps(STATE_3))

    assert state.version == "3.0.0"
    assert state.agv_position is not None
    assert (state.agv_position.x, state.agv_position.position_initialized) == (1.5, True)
    assert (state.battery_state.battery_charge, state.battery_state.reach) == (77.5, 900.0)
    assert state.battery_state.battery_current == -3.0
    assert state.safety_state.e_stop == EStop.NONE
    assert state.node_states[0].node_description == "dock"
    assert state.edge_states[0].edge_description == "aisle"
    assert state.information is not None and state.information[0].info_description == "{}"
    assert state.zone_sets is not None and state.zone_sets[0].zone_set_id == "zs1"
    assert state.zone_requests is not None and state.zone_requests[0].request_status == "REQUESTED"
    assert [e.error_level for e in state.errors] == [ErrorLevel.CRITICAL, ErrorLevel.URGENT]


def test_instant_actions_are_found_apart_from_the_order_actions() -> None:
    """3.0 keeps instant actions out of actionStates: found by actionId, and no reason to think the robot
    busy (the 3.0 idle rule reads only actionStates)."""
    data = copy.deepcopy(STATE_3)
    data.update(nodeStates=[], edgeStates=[], actionStates=[])
    state = parse_state(orjson.dumps(data))

    assert action_status(state, "carter03-startPause-1") == ActionStatus.RUNNING
    assert action_status(state, "carter03-factsheetRequest-1") == ActionStatus.FINISHED
    assert state.instant_action_states is not None
    assert state.instant_action_states[1].result_description == "sent"
    assert is_idle(state)


def test_critical_ends_the_order_urgent_does_not() -> None:
    state = parse_state(orjson.dumps(STATE_3))

    assert [e.error_type for e in order_ending_errors(state)] == ["NODE_UNREACHABLE"]


@pytest.mark.parametrize(
    ("mode", "read_as", "orders", "cancel", "pause"),
    [
        ("TEACH_IN", OperatingMode.TEACHIN, False, False, False),
        ("STARTUP", OperatingMode.STARTUP, False, False, False),
        ("INTERVENED", OperatingMode.INTERVENED, False, True, False),
        ("SEMIAUTOMATIC", OperatingMode.SEMIAUTOMATIC, True, True, True),
    ],
)
def test_3_0_operating_modes(
    mode: str, read_as: OperatingMode, orders: bool, cancel: bool, pause: bool
) -> None:
    state = parse_state(orjson.dumps({**STATE_3, "operatingMode": mode}))

    assert state.operating_mode == read_as
    assert may_receive_orders(state) is orders
    assert may_receive_instant_action(state, "cancelOrder") is cancel
    assert may_receive_instant_action(state, "startPause") is pause


@pytest.mark.parametrize(
    ("wire", "read_as"),
    [
        ("CONNECTION_BROKEN", ConnectionState.CONNECTIONBROKEN),
        ("HIBERNATING", ConnectionState.HIBERNATING),
        ("ONLINE", ConnectionState.ONLINE),
    ],
)
def test_3_0_connection_states(wire: str, read_as: ConnectionState) -> None:
    message = {**HEADER_3, "connectionState": wire}
    validate_message("connection", "3.0.0", message)

    assert parse_connection(orjson.dumps(message)).connection_state == read_as


def test_a_3_0_visualization_reads_its_position() -> None:
    message = {
        **HEADER_3,
        "referenceStateHeaderId": 11,
        "mobileRobotPosition": {"x": 3.0, "y": 4.0, "theta": 0.0, "mapId": "map", "localized": False},
    }
    validate_message("visualization", "3.0.0", message)

    visualization = parse_visualization(orjson.dumps(message))

    assert visualization.agv_position is not None
    assert (visualization.agv_position.x, visualization.agv_position.position_initialized) == (3.0, False)
    assert visualization.reference_state_header_id == 11


def test_a_3_0_factsheet_reads_into_our_shape() -> None:
    factsheet = parse_factsheet(orjson.dumps(FACTSHEET_3))

    assert factsheet.version == "3.0.0"
    assert factsheet.type_specification.agv_kinematic == AgvKinematic.DIFF
    assert factsheet.type_specification.agv_class == "CARRIER"
    assert factsheet.type_specification.navigation_types == [NavigationType.AUTONOMOUS]
    assert factsheet.physical_parameters.speed_max == 1.5
    assert factsheet.protocol_limits.max_string_lens.id_len == 64
    assert factsheet.protocol_limits.timing.min_order_interval == 0.5
    action = factsheet.protocol_features.agv_actions[0]
    assert (action.action_type, action.pause_allowed, action.result_description) == (
        "cancelOrder",
        False,
        "canceled",
    )
    assert factsheet.agv_geometry.envelopes2d is not None
    assert factsheet.agv_geometry.envelopes2d[0].set == "base"
    assert factsheet.load_specification.load_sets is not None
    assert factsheet.load_specification.load_sets[0].max_weight == 80
    assert factsheet.vehicle_config is not None and factsheet.vehicle_config.versions is not None


def test_a_kinematics_beyond_the_enum_is_kept_as_text() -> None:
    data = copy.deepcopy(FACTSHEET_3)
    data["typeSpecification"]["mobileRobotKinematics"] = "ACKERMANN"

    assert parse_factsheet(orjson.dumps(data)).type_specification.agv_kinematic == "ACKERMANN"


def test_orders_to_3_0_robots_link_edges_by_position_and_give_deviation_ellipses() -> None:
    order = route_order(
        mission="m",
        node_index=1,
        attempt=0,
        start=Pose(0.0, 0.0, 0.0, "map"),
        waypoints=[Waypoint(1.0, 0.0, 0.0, "map", 0.25)],
    )

    wire = orjson.loads(encode(order, sample_header("3.0.0")))

    validate_message("order", "3.0.0", wire)
    assert wire["version"] == "3.0.0"
    assert "startNodeId" not in wire["edges"][0] and "endNodeId" not in wire["edges"][0]
    assert wire["nodes"][1]["nodePosition"]["allowedDeviationXY"] == {"a": 0.25, "b": 0.25, "theta": 0.0}
    assert wire["nodes"][0]["nodePosition"]["allowedDeviationXY"] == {"a": 0.5, "b": 0.5, "theta": 0.0}
    # ... and a 3.0 order reads back into our shape (what the simulator's 3.0 robots do).
    assert (
        parse_order(orjson.dumps(wire)).model_dump(
            exclude={"header_id", "timestamp", "version", "manufacturer", "serial_number"}
        )
        == order.model_dump()
    )


def test_a_3_0_ellipse_is_read_as_its_inscribed_circle() -> None:
    wire = orjson.loads(encode(full_order("3.0.0"), sample_header("3.0.0")))
    wire["nodes"][1]["nodePosition"]["allowedDeviationXY"] = {"a": 0.5, "b": 0.2, "theta": 0.3}

    position = parse_order(orjson.dumps(wire)).nodes[1].node_position

    assert position is not None and position.allowed_deviation_xy == 0.2


def test_3_0_instant_actions_must_not_block() -> None:
    hard = instant_actions([instant_action("startPause", "p-1", blocking_type=BlockingType.HARD)])

    with pytest.raises(ProtocolError, match=r"actions\[0\].blockingType"):
        encode(hard, sample_header("3.0.0"))
    validate_message(
        "instantActions",
        "3.0.0",
        orjson.loads(encode(instant_actions([cancel_order("c-1")]), sample_header("3.0.0"))),
    )


@pytest.mark.parametrize("version", SUPPORTED_VERSIONS)
def test_topics_carry_the_major_version(version: str) -> None:
    address = RobotAddress("uagv", "RobotCompany", "carter03", version)

    assert topic_for(address, Topic.ORDER) == f"uagv/v{version[0]}/RobotCompany/carter03/order"


@pytest.mark.parametrize(
    ("said", "spoken"),
    [
        ("2.0.0", "2.0.0"),
        ("2.1.0", "2.1.0"),
        ("3.0.0", "3.0.0"),
        ("3.0.1", "3.0.0"),
        ("3.1.0", "3.0.0"),
        ("2.2.0", "2.1.0"),
        ("1.1.0", None),
        ("4.0.0", None),
        ("three", None),
    ],
)
def test_supported_version(said: str, spoken: str | None) -> None:
    assert supported_version(said) == spoken
