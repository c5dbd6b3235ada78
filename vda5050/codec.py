"""Bytes <-> models. Parsing is tolerant but raises one ``ProtocolError``; encoding is strict.

Both speak the version the message's header names: a received body is read into our shape by its
``version`` (``vda5050.versions.from_wire``), an encoded one is spelled as its header's version.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime
from typing import Any, TypeVar

import orjson
from pydantic import BaseModel, ValidationError

from vda5050.errors import PayloadError, PayloadProblem, ProtocolError
from vda5050.models import (
    Connection,
    ConnectionContent,
    Content,
    Factsheet,
    FactsheetContent,
    Header,
    InstantActions,
    InstantActionsContent,
    Message,
    Order,
    OrderContent,
    Responses,
    ResponsesContent,
    State,
    StateContent,
    Visualization,
    VisualizationContent,
    ZoneSetContent,
    ZoneSetMessage,
)
from vda5050.topics import VERSION_PATTERN, RobotAddress, Topic
from vda5050.versions import from_wire, to_wire

__all__ = [
    "ACTIONS_KEY",
    "LEGACY_INSTANT_ACTIONS_KEY",
    "Header",
    "ProtocolError",
    "encode",
    "header_for",
    "nested_deeper",
    "parse",
    "parse_connection",
    "parse_factsheet",
    "parse_instant_actions",
    "parse_order",
    "parse_responses",
    "parse_state",
    "parse_visualization",
    "parse_zone_set",
    "utc_timestamp",
]

ACTIONS_KEY = "actions"
LEGACY_INSTANT_ACTIONS_KEY = "instantActions"  # VDA 5050 1.1 name, still sent by some masters
PAYLOAD_FIELD = "<payload>"  # ProtocolError.field when the payload as a whole is wrong
HEADER_KEYS = ("headerId", "timestamp", "version", "manufacturer", "serialNumber")
TIMESTAMP_PATTERN = re.compile(r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z")
# Levels of nested objects and arrays a payload may have. The document's own structures need 6; the rest is
# for free-form values (action parameters, 3D envelope data). Deeper payloads are refused before anything
# (validation, Python's json module on the way to PostgreSQL) could recurse through them.
MAX_NESTING = 32

MESSAGE_TYPES: dict[Topic, type[Message]] = {
    Topic.ORDER: Order,
    Topic.INSTANT_ACTIONS: InstantActions,
    Topic.STATE: State,
    Topic.CONNECTION: Connection,
    Topic.VISUALIZATION: Visualization,
    Topic.FACTSHEET: Factsheet,
    Topic.ZONE_SET: ZoneSetMessage,
    Topic.RESPONSES: Responses,
}
# Checked in order with isinstance, so a full message (a Content subclass) is accepted too.
CONTENT_MESSAGE_TYPES: tuple[tuple[type[Content], type[Message], Topic], ...] = (
    (OrderContent, Order, Topic.ORDER),
    (InstantActionsContent, InstantActions, Topic.INSTANT_ACTIONS),
    (StateContent, State, Topic.STATE),
    (ConnectionContent, Connection, Topic.CONNECTION),
    (VisualizationContent, Visualization, Topic.VISUALIZATION),
    (FactsheetContent, Factsheet, Topic.FACTSHEET),
    (ZoneSetContent, ZoneSetMessage, Topic.ZONE_SET),
    (ResponsesContent, Responses, Topic.RESPONSES),
)

ModelT = TypeVar("ModelT", bound=BaseModel)


# --- timestamps and headers ------------------------------------------------------------------------


def utc_timestamp(dt: datetime) -> str:
    """ISO 8601 UTC with millisecond precision and ``Z``, e.g. ``2026-11-22T10:00:00.123Z``."""
    if dt.utcoffset() is None:
        raise ValueError("a naive datetime has no defined UTC time; pass an aware datetime")
    utc = dt.astimezone(UTC)
    return f"{utc:%Y-%m-%dT%H:%M:%S}.{utc.microsecond // 1000:03d}Z"


def header_for(address: RobotAddress, *, header_id: int, at: datetime) -> Header:
    """Header of a message to (or from) ``address``: its manufacturer, serial number and version."""
    return Header(
        header_id=header_id,
        timestamp=utc_timestamp(at),
        version=address.version,
        manufacturer=address.manufacturer,
        serial_number=address.serial_number,
    )


# --- parsing ---------------------------------------------------------------------------------------


def parse_order(payload: bytes | str) -> Order:
    return _validate(Order, _load(Topic.ORDER, payload))


def parse_instant_actions(payload: bytes | str) -> InstantActions:
    """Accepts the ``actions`` key and the legacy 1.1 ``instantActions`` key."""
    data = _load(Topic.INSTANT_ACTIONS, payload)
    if ACTIONS_KEY not in data and LEGACY_INSTANT_ACTIONS_KEY in data:
        data[ACTIONS_KEY] = data.pop(LEGACY_INSTANT_ACTIONS_KEY)
    return _validate(InstantActions, data)


def parse_state(payload: bytes | str) -> State:
    return _validate(State, _load(Topic.STATE, payload))


def parse_connection(payload: bytes | str) -> Connection:
    return _validate(Connection, _load(Topic.CONNECTION, payload))


def parse_visualization(payload: bytes | str) -> Visualization:
    return _validate(Visualization, _load(Topic.VISUALIZATION, payload))


def parse_factsheet(payload: bytes | str) -> Factsheet:
    return _validate(Factsheet, _load(Topic.FACTSHEET, payload))


def parse_zone_set(payload: bytes | str) -> ZoneSetMessage:
    return _validate(ZoneSetMessage, _load(Topic.ZONE_SET, payload))


def parse_responses(payload: bytes | str) -> Responses:
    return _validate(Responses, _load(Topic.RESPONSES, payload))


def parse(topic: Topic, payload: bytes | str) -> Message:
    if topic == Topic.INSTANT_ACTIONS:
        return parse_instant_actions(payload)
    return _validate(MESSAGE_TYPES[Topic(topic)], _load(Topic(topic), payload))


def _load(topic: Topic, payload: bytes | str) -> dict[str, Any]:
    """The JSON object in our shape, whichever version the header names."""
    try:
        data = orjson.loads(payload)
    except orjson.JSONDecodeError as exc:
        raise PayloadError(PAYLOAD_FIELD, _decode_problem(payload, exc), f"not valid JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise PayloadError(
            PAYLOAD_FIELD, PayloadProblem.NOT_OBJECT, f"expected a JSON object, got {type(data).__name__}"
        )
    # Counting brackets is cheap; only a payload with more of them than MAX_NESTING can be too deep.
    brackets = (b"[", b"{") if isinstance(payload, bytes) else ("[", "{")
    if sum(map(payload.count, brackets)) > MAX_NESTING and nested_deeper(data):
        raise PayloadError(PAYLOAD_FIELD, PayloadProblem.TOO_DEEP, f"nested deeper than {MAX_NESTING} levels")
    return from_wire(topic, data)


def _decode_problem(payload: bytes | str, exc: orjson.JSONDecodeError) -> PayloadProblem:
    if isinstance(payload, bytes):
        try:
            payload.decode()
        except UnicodeDecodeError:
            return PayloadProblem.NOT_UTF8
    # orjson's own limit (1024 levels) is far above MAX_NESTING: past it the JSON may be valid, but too deep.
    return PayloadProblem.TOO_DEEP if "depth limit" in str(exc) else PayloadProblem.NOT_JSON


def nested_deeper(data: Any, limit: int = MAX_NESTING) -> bool:
    """Whether a JSON value's objects and arrays nest deeper than `limit` levels (found without recursion,
    whatever the depth)."""
    stack: list[tuple[Any, int]] = [(data, 1)] if isinstance(data, dict | list) else []
    while stack:
        value, depth = stack.pop()
        if depth > limit:
            return True
        children = value.values() if isinstance(value, dict) else value
        stack.extend((child, depth + 1) for child in children if isinstance(child, dict | list))
    return False


def _validate(model: type[ModelT], data: dict[str, Any]) -> ModelT:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise _protocol_error(exc) from exc


def _protocol_error(exc: ValidationError) -> ProtocolError:
    """The first problem, named by its wire path (``nodes[0].nodeId``), plus how many more there are."""
    errors = exc.errors()
    first = errors[0]
    reason = first["msg"]
    if len(errors) > 1:
        reason += f" (and {len(errors) - 1} more problem(s))"
    return ProtocolError(_wire_path(first["loc"]) or PAYLOAD_FIELD, reason)


def _wire_path(loc: tuple[int | str, ...]) -> str:
    path = ""
    for part in loc:
        path += f"[{part}]" if isinstance(part, int) else f".{part}" if path else part
    return path


# --- encoding --------------------------------------------------------------------------------------


def encode(content: Content, header: Header, *, instant_actions_key: str = ACTIONS_KEY) -> bytes:
    """Stamp ``header`` onto ``content`` and return compact JSON (wire names, no nulls).

    The whole message is validated again, so content changed after construction cannot slip through;
    it is spelled as ``header.version`` says (``vda5050.versions.to_wire``);
    ``instant_actions_key="instantActions"`` serves receivers that only know the 1.1 name.
    """
    if instant_actions_key not in (ACTIONS_KEY, LEGACY_INSTANT_ACTIONS_KEY):
        raise ValueError(f"instant_actions_key must be {ACTIONS_KEY!r} or {LEGACY_INSTANT_ACTIONS_KEY!r}")
    _check_header(header)
    message_type, topic = _message_type(content)
    try:
        wire = {**content.model_dump(by_alias=True), **header.model_dump(by_alias=True)}
        message = message_type.model_validate(wire)
    except ValidationError as exc:
        raise _protocol_error(exc) from exc
    body = to_wire(topic, message.model_dump(mode="json", by_alias=True, exclude_none=True), header.version)
    if message_type is InstantActions:
        body[instant_actions_key] = body.pop(ACTIONS_KEY)
    return orjson.dumps(_header_first(body))


def _check_header(header: Header) -> None:
    if not _is_utc_timestamp(header.timestamp):
        raise ProtocolError("timestamp", f"{header.timestamp!r} is not ISO 8601 UTC ending in 'Z'")
    if not VERSION_PATTERN.fullmatch(header.version):
        raise ProtocolError("version", f"{header.version!r} is not Major.Minor.Patch")


def _is_utc_timestamp(text: str) -> bool:
    if not TIMESTAMP_PATTERN.fullmatch(text):
        return False
    try:
        datetime.fromisoformat(text)  # rejects impossible dates such as month 13
    except ValueError:
        return False
    return True


def _message_type(content: Content) -> tuple[type[Message], Topic]:
    for content_type, message_type, topic in CONTENT_MESSAGE_TYPES:
        if isinstance(content, content_type):
            return message_type, topic
    raise TypeError(f"{type(content).__name__} is not a VDA 5050 message content")


def _header_first(body: dict[str, Any]) -> dict[str, Any]:
    """Header keys lead, as in the document's examples, which makes captured traffic easier to read."""
    return {key: body[key] for key in HEADER_KEYS} | body
