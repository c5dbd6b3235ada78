"""Serializer bases every app's API shares: strict bodies, specs, names, poses."""

from collections.abc import Mapping
from contextlib import suppress
from functools import cache
from typing import Any

from django.http import QueryDict
from rest_framework import serializers
from rest_framework.exceptions import ErrorDetail, ValidationError

from kit.api.errors import QueryValidationError, UsageError
from kit.api.fields import JsonStringField, NumberField, ObjectNameField
from kit.api.names import GENERATED_NAME_LENGTH, NAME_PREFIX_MAX_LENGTH, OBJECT_NAME_ALPHABET
from vda5050.orders import DEFAULT_ALLOWED_DEVIATION_THETA, DEFAULT_ALLOWED_DEVIATION_XY


class StrictSerializer(serializers.Serializer):
    """Rejects keys it does not know, like the reference's `extra = "forbid"` models."""

    def to_internal_value(self, data: Any) -> Any:
        unknown = [key for key in data if key not in self.fields] if isinstance(data, Mapping) else []
        message = f"Unknown field. Allowed fields here: {', '.join(self.fields) or 'none'}."
        errors = {key: [ErrorDetail(message, code="extra_forbidden")] for key in unknown}
        try:
            value = super().to_internal_value(data)
        except ValidationError as error:
            # Report the unknown fields together with the other errors, not one after the other.
            if not isinstance(error.detail, Mapping):
                raise
            raise ValidationError({**error.detail, **errors}) from error
        if errors:
            raise ValidationError(errors)
        return value


def body_validated(serializer_class: type[serializers.Serializer], data: Any) -> dict[str, Any]:
    """`data` validated by `serializer_class`, or is_valid(raise_exception=True)'s ValidationError.

    A new serializer deep-copies its whole tree of nested fields, which for a mission costs more than the
    validation; so one instance per class serves every request, in every thread. That is safe because
    run_validation() keeps no state on the serializer or its fields (DRF 3.18; is_valid() does, so it is not
    used on the shared instance). Only the first validations build the nested fields (lazily, as DRF does);
    threads racing there build equal ones.
    """
    with suppress(ValidationError):
        return _shared_serializer(serializer_class).run_validation(data)
    # Invalid (rare): a fresh serializer reports the errors in is_valid()'s exact words.
    body = serializer_class(data=data)
    body.is_valid(raise_exception=True)
    return body.validated_data


def query_validated(serializer_class: type[serializers.Serializer], query: QueryDict) -> dict[str, Any]:
    """The query parameters validated by `serializer_class` (as `body_validated` validates a body), or a
    QueryValidationError: the same error body, located in "query"."""
    try:
        return body_validated(serializer_class, query)
    except ValidationError as error:
        raise QueryValidationError(error.detail) from None


@cache
def _shared_serializer(serializer_class: type[serializers.Serializer]) -> serializers.Serializer:
    return serializer_class()


class SpecSerializer(StrictSerializer):
    """A top-level create or PUT body: the spec of an object; its status belongs to the dispatch engine."""

    def to_internal_value(self, data: Any) -> Any:
        if isinstance(data, Mapping) and "status" in data:
            raise UsageError(
                'Attempted to update "status" with the public API. The status is written only by the '
                "dispatch engine."
            )
        return super().to_internal_value(data)


class ObjectNameSerializer(serializers.Serializer):
    """The `name` or `prefix` of a create body."""

    name = ObjectNameField(
        required=False,
        allow_null=True,
        default=None,
        help_text=(
            f"Unique name ({OBJECT_NAME_ALPHABET}). If neither name nor prefix is given, a random id of "
            f"{GENERATED_NAME_LENGTH} characters is used."
        ),
    )
    prefix = ObjectNameField(
        required=False,
        allow_null=True,
        default=None,
        max_length=NAME_PREFIX_MAX_LENGTH,
        help_text="Instead of name: the object is named <prefix>-<random id>.",
    )


class PoseSerializer(StrictSerializer):
    """A 2D pose on a map: where a robot or a station is."""

    x = NumberField(default=0.0, help_text="x coordinate in metres.")
    y = NumberField(default=0.0, help_text="y coordinate in metres.")
    theta = NumberField(default=0.0, help_text="Orientation in radians.")
    map_id = JsonStringField(default="", allow_blank=True, help_text="Map the pose is on.")


class Pose2DSerializer(PoseSerializer):
    """A pose a robot is sent to (a route waypoint) or is at, with how far from it it may stop."""

    allowedDeviationXY = NumberField(
        default=DEFAULT_ALLOWED_DEVIATION_XY,
        min_value=0.0,
        help_text="Allowed distance from the pose, metres.",
    )
    allowedDeviationTheta = NumberField(
        default=DEFAULT_ALLOWED_DEVIATION_THETA, min_value=0.0, help_text="Allowed angle deviation, radians."
    )
