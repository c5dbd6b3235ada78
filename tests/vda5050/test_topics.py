from __future__ import annotations

import pytest

from vda5050.errors import ProtocolError
from vda5050.topics import (
    RobotAddress,
    RobotIdentity,
    Topic,
    fleet_subscription,
    parse_topic,
    shared_subscription,
    topic_for,
)

ADDRESS = RobotAddress("uagv", "Robot_Co.1", "carter:01-a", "2.1.0")


@pytest.mark.parametrize(
    ("topic", "expected"),
    [
        (Topic.ORDER, "uagv/v2/Robot_Co.1/carter:01-a/order"),
        (Topic.INSTANT_ACTIONS, "uagv/v2/Robot_Co.1/carter:01-a/instantActions"),
        (Topic.STATE, "uagv/v2/Robot_Co.1/carter:01-a/state"),
        (Topic.VISUALIZATION, "uagv/v2/Robot_Co.1/carter:01-a/visualization"),
        (Topic.CONNECTION, "uagv/v2/Robot_Co.1/carter:01-a/connection"),
        (Topic.FACTSHEET, "uagv/v2/Robot_Co.1/carter:01-a/factsheet"),
    ],
)
def test_topic_for_and_parse_topic_round_trip(topic: Topic, expected: str) -> None:
    assert topic_for(ADDRESS, topic) == expected
    assert parse_topic(expected) == (ADDRESS.identity, topic)


@pytest.mark.parametrize(
    ("version", "major"), [("2.0.0", "v2"), ("2.1.0", "v2"), ("3.0.0", "v3"), ("10.2.3", "v10")]
)
def test_major_version(version: str, major: str) -> None:
    assert RobotAddress("uagv", "M", "S", version).major_version == major


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("serialNumber", {"serial_number": "has/slash"}),
        ("serialNumber", {"serial_number": "with space"}),
        ("serialNumber", {"serial_number": ""}),
        ("manufacturer", {"manufacturer": "wild+card"}),
        ("manufacturer", {"manufacturer": "#"}),
        ("interfaceName", {"interface_name": "$SYS"}),
        ("version", {"version": "2.0"}),
        ("version", {"version": "v2.0.0"}),
    ],
)
def test_robot_address_refuses_bad_levels(field: str, kwargs: dict[str, str]) -> None:
    values = {
        "interface_name": "uagv",
        "manufacturer": "M",
        "serial_number": "S",
        "version": "2.0.0",
    } | kwargs

    with pytest.raises(ProtocolError) as raised:
        RobotAddress(**values)

    assert raised.value.field == field


@pytest.mark.parametrize(
    "topic",
    [
        "uagv/v2/M/S",
        "uagv/v2/M/S/state/extra",
        "prefix/uagv/v2/M/S/state",
        "uagv/v2/M//state",
        "uagv/2/M/S/state",
        "uagv/v2/M/S/State",
        "uagv/v2/M/S/orders",
        "",
    ],
)
def test_parse_topic_refuses_malformed_topics(topic: str) -> None:
    with pytest.raises(ProtocolError) as raised:
        parse_topic(topic)

    assert raised.value.field == "topic"


def test_parse_topic_keeps_levels_as_received() -> None:
    identity, topic = parse_topic("iface/v3/Some Vendor/00 17/connection")

    assert identity == RobotIdentity("iface", "v3", "Some Vendor", "00 17")
    assert topic == Topic.CONNECTION


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({}, "+/+/+/+/state"),
        ({"interface_name": "uagv", "major_version": "v2"}, "uagv/v2/+/+/state"),
        ({"interface_name": "uagv", "major_version": "v2", "manufacturer": "M"}, "uagv/v2/M/+/state"),
    ],
)
def test_fleet_subscription(kwargs: dict[str, str], expected: str) -> None:
    assert fleet_subscription(Topic.STATE, **kwargs) == expected


def test_shared_subscription() -> None:
    assert (
        shared_subscription("bridge", Topic.CONNECTION, "uagv", "v2")
        == "$share/bridge/uagv/v2/+/+/connection"
    )


@pytest.mark.parametrize("group", ["", "a/b", "a+", "#"])
def test_shared_subscription_refuses_bad_groups(group: str) -> None:
    with pytest.raises(ProtocolError):
        shared_subscription(group, Topic.STATE)
