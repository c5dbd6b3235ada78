"""The API's request body parser: JSON, bounded in nesting, with only what PostgreSQL can store.

Its own module, free of the views: DRF reads its parser setting while rest_framework.views loads, so the
parser must load without them (kit.api.health imports the views).
"""

import re
from collections.abc import Callable
from typing import Any

from django.conf import settings
from django.http import HttpRequest, HttpResponse, JsonResponse
from rest_framework import parsers, status
from rest_framework.exceptions import APIException


class InputError(APIException):
    """Input refused as a whole rather than field by field (a body too large or nested too deeply, a value
    PostgreSQL cannot store): one schema error at `loc`."""

    status_code = status.HTTP_400_BAD_REQUEST

    def __init__(self, msg: str, *, type: str, loc: tuple[str | int, ...] = ("body",)) -> None:
        super().__init__(msg)
        self.error = {"loc": list(loc), "msg": msg, "type": type}


# What PostgreSQL cannot hold in text or jsonb: NUL, and unpaired surrogates (no UTF-8 for them).
_UNSTORABLE_TEXT = re.compile("[\x00\ud800-\udfff]")


class JSONParser(parsers.JSONParser):
    """DRF's JSON parser, bounded and storable. A body nested deeper than FLEET_API_MAX_JSON_DEPTH is
    refused (Python's decoder gives up on deep nesting with a RecursionError, answered here as a 400); every
    string, key or value, anywhere in the body must be text PostgreSQL can store, so no free-form value
    reaches it only to fail there."""

    def parse(self, stream: Any, media_type: str | None = None, parser_context: Any = None) -> Any:
        try:
            data = super().parse(stream, media_type, parser_context)
        except RecursionError:
            raise _too_deep(("body",)) from None
        body_check(data)
        return data


def _too_deep(loc: tuple[str | int, ...]) -> InputError:
    return InputError(
        f"JSON nested deeper than {settings.API_MAX_JSON_DEPTH} levels.", type="json_too_deep", loc=loc
    )


def body_check(data: Any) -> None:
    """Raise an InputError (located where it is) for nesting too deep or unstorable text. One pass over the
    parsed body, without recursion."""
    max_depth = settings.API_MAX_JSON_DEPTH
    stack: list[tuple[Any, tuple[str | int, ...]]] = [(data, ("body",))]
    while stack:
        value, loc = stack.pop()
        if isinstance(value, dict | list):
            if len(loc) > max_depth:
                raise _too_deep(loc)
            items = value.items() if isinstance(value, dict) else enumerate(value)
            for key, item in items:
                if isinstance(key, str) and _UNSTORABLE_TEXT.search(key):
                    raise _unstorable(loc)
                stack.append((item, (*loc, key)))
        elif isinstance(value, str) and _UNSTORABLE_TEXT.search(value):
            raise _unstorable(loc)


def _unstorable(loc: tuple[str | int, ...]) -> InputError:
    return InputError(
        "Text must not contain NUL characters or unpaired surrogates.", type="invalid_text", loc=loc
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

