"""MQTT topics: ``<interfaceName>/<majorVersion>/<manufacturer>/<serialNumber>/<topic>``."""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import StrEnum

from vda5050.errors import ProtocolError

SINGLE_LEVEL_WILDCARD = "+"
SHARED_SUBSCRIPTION_PREFIX = "$share"
TOPIC_LEVELS = 5

ID_PATTERN = re.compile(r"[A-Za-z0-9_.:\-]+")  # the document's recommended ID characters
VERSION_PATTERN = re.compile(r"(\d+)\.(\d+)\.(\d+)")
MAJOR_VERSION_PATTERN = re.compile(r"v\d+")
SHARE_GROUP_PATTERN = re.compile(r"[^/+#]+")


class Topic(StrEnum):
    ORDER = "order"
    INSTANT_ACTIONS = "instantActions"
    STATE = "state"
    VISUALIZATION = "visualization"
    CONNECTION = "connection"
    FACTSHEET = "factsheet"
    ZONE_SET = "zoneSet"  # 3.0, fleet control -> robot
    RESPONSES = "responses"  # 3.0, fleet control -> robot: answers to zone and edge requests


@dataclass(frozen=True)
class RobotIdentity:
    """Who a topic belongs to, as far as the topic tells (only the major version)."""

    interface_name: str
    major_version: str
    manufacturer: str
    serial_number: str


@dataclass(frozen=True)
class RobotAddress:
    """Everything needed to talk to one robot: topic levels plus the exact protocol version."""

    interface_name: str
    manufacturer: str
    serial_number: str
    version: str = "2.0.0"

    def __post_init__(self) -> None:
        check_id("interfaceName", self.interface_name)
        check_id("manufacturer", self.manufacturer)
        check_id("serialNumber", self.serial_number)
        if not VERSION_PATTERN.fullmatch(self.version):
            raise ProtocolError("version", f"{self.version!r} is not Major.Minor.Patch")

    @property
    def major_version(self) -> str:
        return major_version_of(self.version)

    @property
    def identity(self) -> RobotIdentity:
        return RobotIdentity(self.interface_name, self.major_version, self.manufacturer, self.serial_number)


def major_version_of(version: str) -> str:
    """``"2.1.0"`` -> ``"v2"``, the topic level."""
    match = VERSION_PATTERN.fullmatch(version)
    if match is None:
        raise ProtocolError("version", f"{version!r} is not Major.Minor.Patch")
    return f"v{match.group(1)}"


def check_id(field: str, value: str) -> None:
    """Topic levels and ids we build must use ``A-Z a-z 0-9 _ - . :`` only."""
    if not ID_PATTERN.fullmatch(value):
        raise ProtocolError(field, f"{value!r} must be non-empty and use only A-Z a-z 0-9 _ - . :")


def topic_for(address: RobotAddress, topic: Topic) -> str:
    return "/".join(
        (address.interface_name, address.major_version, address.manufacturer, address.serial_number, topic)
    )


def parse_topic(topic: str) -> tuple[RobotIdentity, Topic]:
    """Split a received topic; anything but exactly five non-empty levels ending in a known topic fails."""
    levels = topic.split("/")
    if len(levels) != TOPIC_LEVELS:
        raise ProtocolError("topic", f"{topic!r} has {len(levels)} levels, expected {TOPIC_LEVELS}")
    interface_name, major, manufacturer, serial_number, name = levels
    if not all(levels):
        raise ProtocolError("topic", f"{topic!r} has an empty level")
    if not MAJOR_VERSION_PATTERN.fullmatch(major):
        raise ProtocolError("topic", f"{major!r} is not a major version like 'v2'")
    try:
        kind = Topic(name)
    except ValueError:
        raise ProtocolError("topic", f"{name!r} is not a VDA 5050 topic") from None
    return RobotIdentity(interface_name, major, manufacturer, serial_number), kind


def fleet_subscription(
    topic: Topic,
    interface_name: str = SINGLE_LEVEL_WILDCARD,
    major_version: str = SINGLE_LEVEL_WILDCARD,
    manufacturer: str = SINGLE_LEVEL_WILDCARD,
) -> str:
    """Filter for ``topic`` of every robot (every manufacturer unless one is given)."""
    return "/".join((interface_name, major_version, manufacturer, SINGLE_LEVEL_WILDCARD, Topic(topic).value))


def shared_subscription(
    group: str,
    topic: Topic,
    interface_name: str = SINGLE_LEVEL_WILDCARD,
    major_version: str = SINGLE_LEVEL_WILDCARD,
    manufacturer: str = SINGLE_LEVEL_WILDCARD,
) -> str:
    """``$share/<group>/<fleet filter>``: the broker spreads messages over the group's subscribers."""
    if not SHARE_GROUP_PATTERN.fullmatch(group):
        raise ProtocolError("group", f"{group!r} must be non-empty without '/', '+', '#'")
    fleet = fleet_subscription(topic, interface_name, major_version, manufacturer)
    return f"{SHARED_SUBSCRIPTION_PREFIX}/{group}/{fleet}"
