"""OpenAPI pieces every view shares: the documented error bodies and examples, the list filters' bounds."""

from typing import Any

from django.conf import settings
from drf_spectacular.utils import (
    OpenApiExample,
    OpenApiResponse,
    PolymorphicProxySerializer,
    inline_serializer,
)
from rest_framework import serializers

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


def names_constraints(result: dict, generator: Any, request: Any, public: bool) -> dict:
    """drf-spectacular hook: what every list's `names` filter (kit.api.filters.ValuesInFilter) enforces but
    cannot state itself: how many names a list may ask for, none empty or with a NUL."""
    for operations in result["paths"].values():
        for parameter in operations.get("get", {}).get("parameters", []):
            if parameter["name"] == "names":
                parameter["schema"].update(maxItems=settings.API_MAX_FILTER_VALUES)
                parameter["schema"]["items"].update(minLength=1, pattern="^[^\\u0000]*$")
    return result
