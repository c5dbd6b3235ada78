"""Project-wide API pieces: the errors and their reference-shaped bodies, object names, row helpers, the
serializer building blocks every app's API shares, and the health endpoint."""

import base64
import json
import uuid
from collections.abc import Callable, Mapping
from contextlib import suppress
from functools import cache
from typing import Any, TypeVar

import django_filters as filters
from django import forms
from django.conf import settings
from django.core.exceptions import RequestDataTooBig, TooManyFieldsSent
from django.core.exceptions import ValidationError as DjangoValidationError
from django.core.validators import RegexValidator
from django.db.models import Model, QuerySet
from django.forms.utils import ErrorDict
from django.http import HttpRequest, HttpResponse, JsonResponse
from drf_spectacular.utils import (
    OpenApiExample,
    OpenApiResponse,
    PolymorphicProxySerializer,
    extend_schema,
    inline_serializer,
)
from rest_framework import serializers, status
from rest_framework.exceptions import ErrorDetail, ParseError, UnsupportedMediaType, ValidationError
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.settings import api_settings
from rest_framework.views import APIView
from rest_framework.views import exception_handler as drf_exception_handler

from fleet.parsers import InputError

M = TypeVar("M", bound=Model)

HEALTH_STATUS = "Mission Dispatch: Running"


# --- errors -----------------------------------------------------------------------------------------


class UsageError(Exception):
    """A request that is well-formed but not allowed (reference: ICSUsageError, 400 with error_code USAGE)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class ObjectError(Exception):
    """A named object is missing or already exists (reference: 400 with `detail`)."""

    def __init__(self, detail: str) -> None:
        super().__init__(detail)
        self.detail = detail

    @classmethod
    def not_found(cls, alias: str, name: str) -> "ObjectError":
        """Missing object on a read or a method (cancel, update, teleop)."""
        return cls(f'Did not find "{alias}" with name "{name}"')

    @classmethod
    def not_found_to_change(cls, name: str) -> "ObjectError":
        """Missing object on PUT or DELETE: the reference words it differently."""
        return cls(f"Could not find object {name}")

    @classmethod
    def exists(cls, alias: str, name: str) -> "ObjectError":
        return cls(f"Object {alias} with name {name} already exists")


class QueryValidationError(ValidationError):
    """Invalid query parameters: reported like invalid body fields, but located in "query"."""

    @classmethod
    def from_form_errors(cls, errors: ErrorDict) -> "QueryValidationError":
        """The errors of a Django form (a FilterSet's) with their messages and codes."""
        return cls(
            {
                field: [
                    ErrorDetail(message, code=error.code or "invalid")
                    for error in field_errors
                    for message in error.messages
                ]
                for field, field_errors in errors.as_data().items()
            }
        )


def body_length_middleware(get_response: Callable[[HttpRequest], HttpResponse]) -> Callable:
    """Refuse a body sent without Content-Length (chunked): Django reads no more of a body than its
    Content-Length says, so the API would take a chunked body for none at all and, say, create a robot
    with a random name instead of the one sent."""

    def middleware(request: HttpRequest) -> HttpResponse:
        if "chunked" in request.META.get("HTTP_TRANSFER_ENCODING", "").lower():
            error = InputError("A body needs a Content-Length header.", type="length_required").error
            return JsonResponse(
                {"detail": [error]},
                status=status.HTTP_400_BAD_REQUEST,
                json_dumps_params={"separators": (",", ":")},
            )
        return get_response(request)

    return middleware


def exception_handler(exc: Exception, context: dict[str, Any]) -> Response | None:
    """Every error body of the API: the reference's shapes, and 400 (not 422 or 415) for invalid input."""
    if isinstance(exc, RequestDataTooBig):
        exc = InputError(
            f"The body is larger than {settings.API_MAX_BODY_BYTES} bytes.", type="body_too_large"
        )
    elif isinstance(exc, TooManyFieldsSent):
        exc = InputError(
            f"More than {settings.DATA_UPLOAD_MAX_NUMBER_FIELDS} query parameters.",
            type="too_many_parameters",
            loc=("query",),
        )
    if isinstance(exc, InputError):
        return Response({"detail": [exc.error]}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, UsageError):
        return Response({"message": exc.message, "error_code": "USAGE"}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, ObjectError):
        return Response({"detail": exc.detail}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, ValidationError):
        where = "query" if isinstance(exc, QueryValidationError) else "body"
        return Response({"detail": schema_errors(exc.detail, [where])}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, ParseError | UnsupportedMediaType):
        error = {"loc": ["body"], "msg": str(exc.detail), "type": "json_invalid"}
        return Response({"detail": [error]}, status=status.HTTP_400_BAD_REQUEST)
    return drf_exception_handler(exc, context)


def schema_errors(detail: Any, loc: list[str | int]) -> list[dict[str, Any]]:
    """DRF's nested error detail as FastAPI's flat list: one {loc, msg, type} per message."""
    if isinstance(detail, Mapping):
        return [
            error
            for key, value in detail.items()
            for error in schema_errors(
                value, loc if key == api_settings.NON_FIELD_ERRORS_KEY else [*loc, key]
            )
        ]
    if isinstance(detail, list):
        errors: list[dict[str, Any]] = []
        for index, item in enumerate(detail):
            errors += schema_errors(item, loc if isinstance(item, str) else [*loc, index])
        return errors
    return [{"loc": loc, "msg": str(detail), "type": getattr(detail, "code", None) or "invalid"}]


# --- object names -----------------------------------------------------------------------------------

# Names are MQTT topic levels and parts of VDA 5050 ids, so they keep to a safe alphabet.
OBJECT_NAME_MAX_LENGTH = 100
OBJECT_NAME_ALPHABET = "A-Z a-z 0-9 _ - . :"
object_name_validator = RegexValidator(
    r"\A[A-Za-z0-9_.:-]+\Z", message=f"Use only the characters {OBJECT_NAME_ALPHABET}.", code="invalid_name"
)
# base32 of a uuid4 without padding, as the reference generates names.
GENERATED_NAME_LENGTH = 26
# `<prefix>-<generated>` must still fit in a name.
NAME_PREFIX_MAX_LENGTH = OBJECT_NAME_MAX_LENGTH - GENERATED_NAME_LENGTH - 1


def object_name_check(name: str, *, what: str) -> None:
    """Raise a UsageError unless `name` is a valid name for a robot, mission or node (`what` names it)."""
    if len(name) > OBJECT_NAME_MAX_LENGTH:
        raise UsageError(f"{what} {name!r} is longer than {OBJECT_NAME_MAX_LENGTH} characters.")
    try:
        object_name_validator(name)
    except DjangoValidationError as error:
        raise UsageError(f"{what} {name!r} is invalid: {error.messages[0]}") from error


def object_name_for_create(*, name: str | None, prefix: str | None, what: str) -> str:
    """The name of a new object: `name`, `<prefix>-<random id>`, or a random id when neither is given."""
    if name is not None and prefix is not None:
        raise UsageError('Cannot have both "name" and "prefix"')
    if name is None:
        generated = base64.b32encode(uuid.uuid4().bytes).decode().rstrip("=").lower()
        name = generated if prefix is None else f"{prefix}-{generated}"
    object_name_check(name, what=what)
    return name


# --- rows ---------------------------------------------------------------------------------------------


def object_name_valid(name: str) -> bool:
    return len(name) <= OBJECT_NAME_MAX_LENGTH and object_name_validator.regex.search(name) is not None


def object_get(queryset: QuerySet[M], *, alias: str, name: str, to_change: bool = False) -> M:
    """The object called `name`, or the reference's 400 (worded differently for PUT and DELETE). A name no
    object can have is not looked up: it may hold what PostgreSQL refuses in text (NUL)."""
    obj = queryset.filter(pk=name).first() if object_name_valid(name) else None
    if obj is None:
        raise ObjectError.not_found_to_change(name) if to_change else ObjectError.not_found(alias, name)
    return obj


def lock_row(obj: M) -> M:
    """`obj` re-read and locked until the transaction ends, so concurrent writers see each other's changes."""
    locked = type(obj)._default_manager.select_for_update().filter(pk=obj.pk).first()
    if locked is None:
        raise ObjectError.not_found_to_change(obj.pk)
    return locked


# --- serializer building blocks ----------------------------------------------------------------------


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


# --- query filters -------------------------------------------------------------------------------------


class StrictFilterSet(filters.FilterSet):
    """Query filters that refuse an empty value (`?state=`), which django-filter would take as no filter,
    and a value with a NUL, which some form fields let through and PostgreSQL cannot compare."""

    def is_valid(self) -> bool:
        for name in self.filters:
            values = self.data.getlist(name) if hasattr(self.data, "getlist") else [self.data.get(name)]
            if "" in values:
                self.form.add_error(name, forms.ValidationError("Must not be empty.", code="blank"))
            elif any(isinstance(value, str) and "\x00" in value for value in values):
                error = forms.ValidationError("Must not contain NUL characters.", code="null_characters")
                self.form.add_error(name, error)
        return super().is_valid()


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


DEFAULT_ALLOWED_DEVIATION_XY = 0.1
DEFAULT_ALLOWED_DEVIATION_THETA = 0.0


class Pose2DSerializer(StrictSerializer):
    """A 2D pose on a map: a route waypoint, or where a robot is."""

    x = NumberField(default=0.0, help_text="x coordinate in metres.")
    y = NumberField(default=0.0, help_text="y coordinate in metres.")
    theta = NumberField(default=0.0, help_text="Orientation in radians.")
    map_id = JsonStringField(default="", allow_blank=True, help_text="Map the pose is on.")
    allowedDeviationXY = NumberField(
        default=DEFAULT_ALLOWED_DEVIATION_XY,
        min_value=0.0,
        help_text="Allowed distance from the pose, metres.",
    )
    allowedDeviationTheta = NumberField(
        default=DEFAULT_ALLOWED_DEVIATION_THETA, min_value=0.0, help_text="Allowed angle deviation, radians."
    )


# --- documented error bodies ---------------------------------------------------------------------------

_OBJECT_ERROR = inline_serializer("ObjectError", {"detail": serializers.CharField()})
_USAGE_ERROR = inline_serializer(
    "UsageError", {"message": serializers.CharField(), "error_code": serializers.ChoiceField(["USAGE"])}
)
_SCHEMA_ERROR = inline_serializer(
    "SchemaError",
    {
        "detail": inline_serializer(
            "SchemaErrorItem",
            {
                "loc": serializers.ListField(
                    child=serializers.JSONField(),
                    help_text='Where: "body" or "query", then field names and list indexes.',
                ),
                "msg": serializers.CharField(),
                "type": serializers.CharField(),
            },
            many=True,
        )
    },
)


# The success body of DELETE and of POST /mission/{name}/cancel.
DETAIL_RESPONSE = inline_serializer("Detail", {"detail": serializers.CharField()})


def bad_request(*examples: OpenApiExample) -> OpenApiResponse:
    """The documented 400 response: a missing/duplicate object, a refused request, or invalid input."""
    return OpenApiResponse(
        response=PolymorphicProxySerializer(
            component_name="Error",
            serializers=[_OBJECT_ERROR, _USAGE_ERROR, _SCHEMA_ERROR],
            resource_type_field_name=None,
        ),
        description=(
            'A missing or duplicate object ({"detail": "..."}), a request that is not allowed '
            '({"message": "...", "error_code": "USAGE"}) or invalid input '
            '({"detail": [{"loc": [...], "msg": "...", "type": "..."}]}).'
        ),
        examples=list(examples),
    )


SCHEMA_ERROR_EXAMPLE = OpenApiExample(
    "Invalid input",
    value={
        "detail": [
            {"loc": ["body", "heartbeat_timeout"], "msg": "Must be greater than 0.", "type": "greater_than"}
        ]
    },
    response_only=True,
    status_codes=["400"],
)


# --- health ---------------------------------------------------------------------------------------------


class HealthView(APIView):
    """Liveness of the API process: public, for load balancers and probes."""

    authentication_classes = []
    permission_classes = []

    @extend_schema(
        operation_id="health",
        summary="Health check",
        tags=["health"],
        responses=inline_serializer("Health", {"status": serializers.CharField()}),
        examples=[OpenApiExample("Running", value={"status": HEALTH_STATUS})],
    )
    def get(self, request: Request) -> Response:
        return Response({"status": HEALTH_STATUS})
