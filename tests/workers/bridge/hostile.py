"""Hostile input for the bridge: every class of bad message on every topic it reads, each with the counter and
reason the bridge must count it under. The in-process tests (test_hostile.py) hand the corpus to a bridge; the
end-to-end test (tests/e2e/test_hostile_mqtt.py) publishes it through Mosquitto to the real bridge process.

A robot's history comes first (`history`): a connection loss, then a state (which brings it back online), a
factsheet and a visualization; the corpus then replays those, sends older ones, and breaks them every other
way. Nothing in the corpus may change what the history stored.
"""

from dataclasses import dataclass
from typing import Any

import orjson
from django.conf import settings

from tests.dispatch.builders import robot_state
from tests.vda5050.samples import full_factsheet
from tests.workers.bridge.messages import topic, wire
from vda5050.models import AgvPosition, ConnectionContent, ConnectionState, VisualizationContent
from workers import metrics
from workers.bridge.gate import Drop, Ignored

SUBSCRIBED = ("state", "connection", "factsheet", "visualization")
# A field of each topic's message given a value of the wrong type.
WRONG_TYPES: dict[str, tuple[str, Any]] = {
    "state": ("batteryState", "full"),
    "connection": ("connectionState", 7),
    "factsheet": ("typeSpecification", []),
    "visualization": ("agvPosition", "here"),
}


@dataclass(frozen=True)
class Case:
    id: str
    topic: str
    payload: bytes
    counter: str  # metrics.MESSAGES_INVALID or metrics.MESSAGES_IGNORED
    reason: str
    label: str  # the counter's topic label
    via_broker: bool = True  # whether Mosquitto delivers it on the bridge's subscriptions at all


def content(kind: str, *, old: bool = False) -> Any:
    """What the robot sends on `kind`; `old`: different content, as an older message would hold."""
    if kind == "state":
        return robot_state(battery=10.0 if old else 55.0, pose=(3.0, 4.0, 0.25, "old" if old else "map"))
    if kind == "connection":
        return ConnectionContent(connection_state=ConnectionState.CONNECTIONBROKEN)
    if kind == "factsheet":
        factsheet = full_factsheet()
        factsheet.type_specification.series_name = "old" if old else "carter"
        return factsheet
    x = 0.0 if old else 7.0
    position = AgvPosition(x=x, y=8.0, theta=0.5, map_id="map", position_initialized=True)
    return VisualizationContent(agv_position=position)


# When each history message was sent (s after tests.workers.bridge.messages.T0): the connection loss
# before the state.
HISTORY_AT = {"connection": 1.0, "state": 2.0, "factsheet": 2.0, "visualization": 3.0}


def history(serial: str) -> list[tuple[str, bytes]]:
    """The robot's good messages, in the order it sent them (headerId 1 on each topic)."""
    return [(topic(serial, kind), wire(serial, content(kind), at=at)) for kind, at in HISTORY_AT.items()]


def corpus(serial: str, stranger: str) -> list[Case]:
    """Every hostile case on every topic, for the robot `serial` after its `history`; `stranger` is a serial
    number no robot has."""
    cases: list[Case] = []
    for kind in SUBSCRIBED:
        cases += _cases(kind, serial, stranger)
    return cases


def _cases(kind: str, serial: str, stranger: str) -> list[Case]:
    at = HISTORY_AT[kind]
    good = wire(serial, content(kind), at=at)
    message = orjson.loads(good)
    own = topic(serial, kind)

    def invalid(case_id: str, payload: bytes, reason: Drop, on: str = own, via_broker: bool = True) -> Case:
        return Case(f"{kind}-{case_id}", on, payload, metrics.MESSAGES_INVALID, reason, kind, via_broker)

    def ignored(case_id: str, payload: bytes, reason: Ignored) -> Case:
        return Case(f"{kind}-{case_id}", own, payload, metrics.MESSAGES_IGNORED, reason, kind)

    def changed(**fields: Any) -> bytes:
        return orjson.dumps({**message, **fields})

    def with_number(literal: bytes) -> bytes:
        return good.replace(b'"headerId":1', b'"headerId":' + literal, 1)

    wrong_field, wrong_value = WRONG_TYPES[kind]
    nested = {"x": 0}
    for _ in range(40):
        nested = {"x": nested}
    return [
        invalid("truncated-json", good[:-1], Drop.NOT_JSON),
        invalid("not-json", b"state: fine", Drop.NOT_JSON),
        invalid("nan", with_number(b"NaN"), Drop.NOT_JSON),
        invalid("infinity", with_number(b"-Infinity"), Drop.NOT_JSON),
        invalid("beyond-double", with_number(b"1e400"), Drop.NOT_JSON),
        invalid("invalid-utf8", b'{"note":"\xff\xfe",' + good[1:], Drop.NOT_UTF8),
        invalid("lone-surrogate", b'{"note":"\\ud800",' + good[1:], Drop.NOT_JSON),
        invalid("null", b"null", Drop.NOT_OBJECT),
        invalid("number", b"42", Drop.NOT_OBJECT),
        invalid("string", b'"hello"', Drop.NOT_OBJECT),
        invalid("list", b"[" + good + b"]", Drop.NOT_OBJECT),
        invalid("wrong-type", changed(**{wrong_field: wrong_value}), Drop.SCHEMA),
        invalid("header-id-text", changed(headerId="one"), Drop.SCHEMA),
        invalid("header-id-beyond-64-bits", with_number(str(2**70).encode()), Drop.SCHEMA),
        invalid("header-id-beyond-uint32", with_number(str(2**32).encode()), Drop.SCHEMA),
        invalid("header-id-negative", with_number(b"-1"), Drop.SCHEMA),
        invalid("timestamp-not-a-time", changed(timestamp="yesterday"), Drop.SCHEMA),
        invalid("from-the-future", changed(timestamp="2100-01-01T00:00:00.000Z"), Drop.FUTURE),
        invalid("nul-in-value", changed(note="stuck\x00here"), Drop.NUL),
        invalid("nul-in-key", changed(**{"no\x00te": 1}), Drop.NUL),
        invalid("deep", changed(note=nested), Drop.TOO_DEEP),
        invalid(
            "deeper-than-orjson", good[:-1] + b',"note":' + b"[" * 5000 + b"]" * 5000 + b"}", Drop.TOO_DEEP
        ),
        invalid("huge", changed(note="x" * settings.MQTT_MAX_PAYLOAD_BYTES), Drop.TOO_LARGE),
        invalid("other-serial-number", changed(serialNumber=stranger), Drop.HEADER_MISMATCH),
        invalid("other-manufacturer", changed(manufacturer="OtherCompany"), Drop.HEADER_MISMATCH),
        invalid(
            "unknown-robot",
            wire(stranger, content(kind), at=at + 10),
            Drop.UNKNOWN_ROBOT,
            topic(stranger, kind),
        ),
        invalid("other-major-version", good, Drop.UNKNOWN_ROBOT, f"uagv/v3/RobotCompany/{serial}/{kind}"),
        invalid("other-interface", good, Drop.UNKNOWN_ROBOT, f"agv/v2/RobotCompany/{serial}/{kind}"),
        invalid("bad-version-level", good, Drop.TOPIC, f"uagv/2.0/RobotCompany/{serial}/{kind}"),
        invalid("empty-level", good, Drop.TOPIC, f"uagv/v2//{serial}/{kind}"),
        invalid(
            "too-many-levels", good, Drop.TOPIC, f"uagv/v2/RobotCompany/{serial}/x/{kind}", via_broker=False
        ),
        invalid("too-few-levels", good, Drop.TOPIC, f"uagv/RobotCompany/{serial}/{kind}", via_broker=False),
        ignored("replayed", good, Ignored.REPLAYED),
        ignored("older", wire(serial, content(kind, old=True), header_id=7, at=at - 1), Ignored.STALE),
        ignored(
            "same-time-lower-header-id",
            wire(serial, content(kind, old=True), header_id=0, at=at),
            Ignored.STALE,
        ),
    ]
