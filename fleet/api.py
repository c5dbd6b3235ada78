"""Project-wide API pieces: the error handler that turns domain errors into the reference's bodies."""

from typing import Any

from rest_framework import status
from rest_framework.response import Response
from rest_framework.views import exception_handler as drf_exception_handler


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


def exception_handler(exc: Exception, context: dict[str, Any]) -> Response | None:
    if isinstance(exc, UsageError):
        return Response({"message": exc.message, "error_code": "USAGE"}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, ObjectError):
        return Response({"detail": exc.detail}, status=status.HTTP_400_BAD_REQUEST)
    return drf_exception_handler(exc, context)
