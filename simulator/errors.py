"""The errors a simulated robot reports in its state: their types and references, and the list it keeps.

A refused order or instant-actions message becomes a WARNING that references it; a failed order action
or a simulated failure a FATAL error (the robot abandons its order). A 3.0 robot names the predefined
error types as 3.0 does.
"""

from __future__ import annotations

from typing import Any

import orjson

from simulator.actions import ActionRun
from simulator.outbox import Outbox
from vda5050.models import Error, ErrorLevel, ErrorReference, Order
from vda5050.topics import Topic

# errorType values: the document's predefined ones, plus our own (vendor-specific) names.
VALIDATION_ERROR = "validationError"
ORDER_ERROR = "orderError"
ORDER_UPDATE_ERROR = "orderUpdateError"
NO_ORDER_TO_CANCEL = "noOrderToCancel"
ACTION_ERROR = "actionError"
# 2.1 names no error types for maps (vendor-specific); 3.0 does (ERROR_TYPES_3).
DUPLICATE_MAP = "duplicateMap"
UNKNOWN_MAP = "unknownMap"
# 3.0 zone sets (only 3.0 robots hold them): the predefined duplicate, and our own unknown set.
DUPLICATE_ZONE_SET = "DUPLICATE_ZONE_SET"
UNKNOWN_ZONE_SET = "unknownZoneSet"
SIMULATED_FAILURE = "simulatedFailure"
# 3.0 renamed the predefined ones (UPPER_SNAKE); a 3.0 robot reports those names.
ERROR_TYPES_3 = {
    VALIDATION_ERROR: "VALIDATION_FAILURE",
    ORDER_ERROR: "INVALID_ORDER_ACTION",
    ORDER_UPDATE_ERROR: "OUTDATED_ORDER_UPDATE",
    NO_ORDER_TO_CANCEL: "NO_ORDER_TO_CANCEL",
    DUPLICATE_MAP: "DUPLICATE_MAP",
    UNKNOWN_MAP: "UNKNOWN_MAP_ID",
}

References = list[tuple[str, str]]


class Rejection(Exception):
    """An order (or instant-actions message) the robot refuses; becomes a WARNING in ``errors``."""

    def __init__(self, error_type: str, description: str) -> None:
        super().__init__(description)
        self.error_type = error_type
        self.description = description


class ErrorReport:
    """The robot's ``errors``: each error once, the newest last."""

    def __init__(self, outbox: Outbox, *, is_3: bool) -> None:
        self.errors: list[Error] = []
        self._outbox = outbox
        self._is_3 = is_3

    def add(self, error_type: str, description: str, level: ErrorLevel, references: References) -> None:
        """Append an error; one repeating an existing error (but for the headerId) replaces it, so a
        master resending a rejected order does not grow the list."""
        error = Error(
            error_type=ERROR_TYPES_3.get(error_type, error_type) if self._is_3 else error_type,
            error_description=description,
            error_level=level,
            error_references=[
                ErrorReference(reference_key=key, reference_value=value) for key, value in references
            ],
        )
        identity = error_identity(error)
        self.errors = [existing for existing in self.errors if error_identity(existing) != identity]
        self.errors.append(error)
        self._outbox.state_changed = True

    def warn(self, error_type: str, description: str, references: References) -> None:
        self.add(error_type, description, ErrorLevel.WARNING, references)

    def refuse_action(self, run: ActionRun, error_type: str, reason: str) -> None:
        """An instant action the robot cannot carry out: FAILED at once, with a WARNING naming it."""
        run.fail(reason)
        self.warn(error_type, reason, [("actionId", run.action.action_id)])

    def clear(self) -> None:
        self.errors.clear()


def error_identity(error: Error) -> tuple[Any, ...]:
    references = tuple(
        (reference.reference_key, reference.reference_value)
        for reference in error.error_references or ()
        if reference.reference_key != "headerId"
    )
    return error.error_type, error.error_description, error.error_level, references


def order_references(order: Order) -> References:
    return [
        ("headerId", str(order.header_id)),
        ("topic", Topic.ORDER.value),
        ("orderId", order.order_id),
        ("orderUpdateId", str(order.order_update_id)),
    ]


def raw_references(kind: Topic, payload: bytes) -> References:
    """References of a message that did not parse: whatever of them the raw JSON has."""
    try:
        data: Any = orjson.loads(payload)
    except orjson.JSONDecodeError:
        data = None
    references = [("topic", kind.value)]
    if isinstance(data, dict):
        keys = ("headerId", "orderId", "orderUpdateId") if kind == Topic.ORDER else ("headerId",)
        references += [(key, str(data[key])) for key in keys if key in data]
    return references
