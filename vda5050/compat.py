"""Vehicle compatibility rules: named, tested recognitions of robot stacks that bend the standard.

Each rule says how a robot shows the quirk (in its own state) and what we do about it; the dispatch step
applies it and records it on the robot (README, "Vehicle compatibility rules"). None is a guess: a rule
fires only on the robot's own answer, never on its manufacturer or version.
"""

from __future__ import annotations

import re
from enum import StrEnum

from vda5050.models import Error, ErrorType, State
from vda5050.topics import Topic

VALIDATION_ERROR_TYPES = frozenset({ErrorType.VALIDATION_ERROR, ErrorType.VALIDATION_FAILURE})
NO_ORDER_TO_CANCEL_TYPES = frozenset({ErrorType.NO_ORDER_TO_CANCEL, ErrorType.NO_ORDER_TO_CANCEL_3})
# The 1.1 key named as a key: a JSON pointer (`#/instantActions`, vda-5050-lib), quoted, or "property
# instantActions" (jsonschema's "'instantActions' is a required property" is quoted). The topic's name
# alone (`topic: instantActions`, "invalid instantActions message") names no key.
LEGACY_KEY_NAMED = re.compile(r"(?:#/|['\"`]|\bproperty\s+)instantActions\b")
TOPIC_REFERENCE_KEY = "topic"
ACTION_ID_REFERENCE_KEY = "actionid"


class Rule(StrEnum):
    """The compatibility rules, by the name recorded on a robot."""

    # The robot rejects `actions` with a validation error that names the key `instantActions` (npm
    # vda-5050-lib 1.4.0, "Invalid VDA 5050 InstantActions at #/allOf/1/required, #/instantActions"):
    # its instant actions go out under the 1.1 key from then on, and the unacknowledged ones again.
    LEGACY_INSTANT_ACTIONS_KEY = "legacy_instant_actions_key"
    # The robot answers a cancelOrder it has no order for with a `noOrderToCancel` error naming the
    # action, but never reports the action's state (vda-5050-lib 1.4.0): the cancel counts as FAILED, which
    # is what the document says the robot should have reported.
    CANCEL_REFUSED_BY_ERROR_ONLY = "cancel_refused_by_error_only"
    # The robot takes an order update (its state shows the orderUpdateId) and then shows no progress on it,
    # not paused, driving or reporting an error, for FLEET_ORDER_STALL_SECONDS (vda5050-sdk 0.2.0, whose
    # executor fails internally on an update that extends a finished route): the update is canceled, the
    # rest goes out as a new order, and the robot is sent no routes ahead from then on.
    ORDER_UPDATE_NOT_EXECUTED = "order_update_not_executed"


def actions_key_rejection(state: State) -> Error | None:
    """The error by which the robot says it reads instant actions only under the 1.1 key."""
    for error in state.errors:
        if error.error_type in VALIDATION_ERROR_TYPES and _names_legacy_key(error):
            return error
    return None


def cancel_refusal(state: State, action_id: str) -> Error | None:
    """The `noOrderToCancel` error by which the robot refused this cancelOrder."""
    for error in state.errors:
        if error.error_type in NO_ORDER_TO_CANCEL_TYPES and any(
            reference.reference_key.replace("_", "").lower() == ACTION_ID_REFERENCE_KEY
            and reference.reference_value.strip() == action_id
            for reference in error.error_references or ()
        ):
            return error
    return None


def _names_legacy_key(error: Error) -> bool:
    if LEGACY_KEY_NAMED.search(error.error_description or ""):
        return True
    return any(
        reference.reference_key != TOPIC_REFERENCE_KEY and reference.reference_value == Topic.INSTANT_ACTIONS
        for reference in error.error_references or ()
    )
