"""Serializer fields and validators every app's API shares: JSON types without coercion, bounded numbers."""

import json
from typing import Any

from django.conf import settings
from rest_framework import serializers

from kit.api.names import OBJECT_NAME_MAX_LENGTH, object_name_validator

# Durations (timeouts) in seconds at most: about 31 years, far inside what Python's timedelta and
# PostgreSQL's interval hold, so no arithmetic on a stored duration overflows.
MAX_SECONDS = 1e9
# Integers in action parameters fit what the VDA 5050 encoder writes.
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


class NumberField(serializers.FloatField):
    """A JSON number that must be finite: NaN and infinity (JSON `1e999` parses as infinity) are no valid
    input, nor are strings and booleans (the schema says number; no coercion)."""

    default_error_messages = {"invalid": "A finite number is required."}

    def to_internal_value(self, data: Any) -> float:
        if isinstance(data, bool) or not isinstance(data, int | float):
            self.fail("invalid")
        return super().to_internal_value(data)


class JsonIntegerField(serializers.IntegerField):
    """A JSON integer (a number without fraction, 5.0 included); no strings or booleans."""

    def to_internal_value(self, data: Any) -> int:
        if isinstance(data, bool) or not isinstance(data, int | float):
            self.fail("invalid")
        return super().to_internal_value(data)


class JsonBooleanField(serializers.BooleanField):
    """A JSON true or false; no strings ("yes") or numbers (1)."""

    def to_internal_value(self, data: Any) -> bool:
        if not isinstance(data, bool):
            self.fail("invalid")
        return data


class JsonStringField(serializers.CharField):
    """A JSON string kept as sent: numbers are not turned into text, spaces are not trimmed (as in the
    reference); at most FLEET_API_MAX_TEXT_LENGTH characters unless `max_length` says less. DRF already
    refuses NUL characters and unpaired surrogates, which PostgreSQL cannot store."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("trim_whitespace", False)
        kwargs.setdefault("max_length", settings.API_MAX_TEXT_LENGTH)
        super().__init__(**kwargs)

    def to_internal_value(self, data: Any) -> str:
        if not isinstance(data, str):
            self.fail("invalid")
        return super().to_internal_value(data)


class ObjectNameField(JsonStringField):
    """A name as robots, missions, tree nodes and VDA 5050 topic levels have it: at most
    OBJECT_NAME_MAX_LENGTH characters (unless `max_length` says less) of OBJECT_NAME_ALPHABET."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("max_length", OBJECT_NAME_MAX_LENGTH)
        kwargs.setdefault("validators", [object_name_validator])
        super().__init__(**kwargs)


def validate_positive(value: float) -> None:
    if value <= 0:
        raise serializers.ValidationError("Must be greater than 0.", code="greater_than")


def validate_free_json(value: Any) -> None:
    """Free-form JSON (action parameters, notify data): finite numbers only (JSON `1e999` is infinity,
    which jsonb cannot hold), at most FLEET_API_MAX_PARAMETERS_BYTES as JSON."""
    try:
        text = json.dumps(value, ensure_ascii=False, separators=(",", ":"), allow_nan=False)
    except ValueError:
        raise serializers.ValidationError("Numbers must be finite.", code="finite_number") from None
    size = len(text.encode())
    if size > settings.API_MAX_PARAMETERS_BYTES:
        raise serializers.ValidationError(
            f"Larger than {settings.API_MAX_PARAMETERS_BYTES} bytes as JSON ({size}).", code="too_large"
        )


def validate_int64(value: Any) -> None:
    """Integers anywhere in `value` fit in 64 bits, the range of the VDA 5050 encoder (orjson)."""
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, int) and not isinstance(item, bool) and not INT64_MIN <= item <= INT64_MAX:
            raise serializers.ValidationError(f"Integer {item} does not fit in 64 bits.", code="int64")
