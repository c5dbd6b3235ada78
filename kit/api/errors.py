"""The API's errors and their reference-shaped bodies, in one exception handler."""

from collections.abc import Mapping
from typing import Any

from django.conf import settings
from django.core.exceptions import RequestDataTooBig, TooManyFieldsSent
from django.forms.utils import ErrorDict
from rest_framework import status
from rest_framework.exceptions import ErrorDetail, ParseError, UnsupportedMediaType, ValidationError
from rest_framework.response import Response
from rest_framework.settings import api_settings
from rest_framework.views import exception_handler as drf_exception_handler

from kit.api.parsers import InputError


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
