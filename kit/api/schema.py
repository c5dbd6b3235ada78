"""OpenAPI pieces every view shares: the documented error bodies and examples."""


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
