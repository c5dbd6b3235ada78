"""Validate messages against the official VDA 5050 JSON schemas (2.0.0, 2.1.0 and 3.0.0).

Reusable from any test suite: ``validate_message("order", "2.0.0", message_dict)`` raises
``jsonschema.ValidationError`` when the message does not conform. Known upstream defects are patched
at load time, each one below with the reason (the document wins where it and the schema differ).

3.0.0 messages are checked against the released schemas (tag 3.0.0) and against the errata on upstream
``main`` (``3.0.0-main-fixes``), both: a message passes only if it conforms to each. Two released files
are unusable and are replaced by their ``main`` version (``SCHEMA_SUBSTITUTES``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from datetime import datetime
from functools import cache
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator, FormatChecker

SCHEMA_DIR = Path(__file__).parent / "schema_files"
VERSIONS = ("2.0.0", "2.1.0", "3.0.0")
TOPIC_NAMES = ("order", "instantActions", "state", "connection", "factsheet", "visualization")
MAIN_FIXES = "3.0.0-main-fixes"
# The schema set each version is also checked against.
ALSO_CHECKED = {"3.0.0": MAIN_FIXES}
# Released 3.0.0 files no correct message can pass, replaced by main's: the factsheet requires
# ``mobileRobotKinematic`` (the property is ``mobileRobotKinematics``), types pauseAllowed/cancelAllowed
# as strings and has a key ``"batteryCharging "``; zoneSet has keys with trailing spaces.
SCHEMA_SUBSTITUTES = {("3.0.0", "factsheet"): MAIN_FIXES, ("3.0.0", "zoneSet"): MAIN_FIXES}

# 2.0.0/state.schema line 221 and 3.0.0's factsheet, order and visualization are not strict JSON.
TRAILING_COMMA = re.compile(r",(\s*[}\]])")
RFC3339_DATE_TIME = re.compile(r"\d{4}-\d{2}-\d{2}[Tt]\d{2}:\d{2}:\d{2}(\.\d+)?([Zz]|[+-]\d{2}:\d{2})")


def _action_status_paused(schema: dict[str, Any]) -> None:
    """2.1.0 state lacks PAUSED although the 2.1.0 document lists it (upstream issue #356)."""
    status = schema["properties"]["actionStates"]["items"]["properties"]["actionStatus"]
    status["enum"].append("PAUSED")


def _blocking_types_items(schema: dict[str, Any]) -> None:
    """``blockingTypes`` puts its enum on the array itself, so no non-empty list could ever pass."""
    actions = schema["properties"]["protocolFeatures"]["properties"]["agvActions"]["items"]
    blocking_types = actions["properties"]["blockingTypes"]
    blocking_types["items"] = {"type": "string", "enum": blocking_types.pop("enum")}


def _envelope_description_string(schema: dict[str, Any]) -> None:
    """2.1.0 types ``envelopes3d[].description`` integer; it is free text (string in 2.0.0)."""
    envelope = schema["properties"]["agvGeometry"]["properties"]["envelopes3d"]["items"]
    envelope["properties"]["description"]["type"] = "string"


ERRATA: dict[tuple[str, str], tuple[Callable[[dict[str, Any]], None], ...]] = {
    ("2.0.0", "factsheet"): (_blocking_types_items,),
    ("2.1.0", "factsheet"): (_blocking_types_items, _envelope_description_string),
    ("2.1.0", "state"): (_action_status_paused,),
}


@cache
def load_schema(topic_name: str, version: str) -> dict[str, Any]:
    directory = SCHEMA_SUBSTITUTES.get((version, topic_name), version)
    text = (SCHEMA_DIR / directory / f"{topic_name}.schema").read_text(encoding="utf-8")
    schema = json.loads(TRAILING_COMMA.sub(r"\1", text))
    for patch in ERRATA.get((version, topic_name), ()):
        patch(schema)
    return schema


def _is_date_time(value: object) -> bool:
    """RFC 3339 date-time (jsonschema only checks it when an optional package is installed)."""
    if not isinstance(value, str):
        return True
    if not RFC3339_DATE_TIME.fullmatch(value):
        return False
    datetime.fromisoformat(value.upper())  # raises on impossible dates such as month 13
    return True


FORMAT_CHECKER = FormatChecker(formats=())
FORMAT_CHECKER.checks("date-time", raises=ValueError)(_is_date_time)


@cache
def validator(topic_name: str, version: str) -> Draft202012Validator:
    schema = load_schema(topic_name, version)
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema, format_checker=FORMAT_CHECKER)


def validate_message(topic_name: str, version: str, message: dict[str, Any]) -> None:
    """Raise ``jsonschema.ValidationError`` unless ``message`` conforms to the official schema(s)."""
    validator(topic_name, version).validate(message)
    if version in ALSO_CHECKED:
        validator(topic_name, ALSO_CHECKED[version]).validate(message)
