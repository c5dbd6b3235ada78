"""The OpenAPI side of access: the bearer scheme (Swagger UI's "Authorize"), the session scheme, and the
401/403 answers of every protected operation."""

from typing import Any

from django.conf import settings
from drf_spectacular.authentication import SessionScheme
from drf_spectacular.extensions import OpenApiAuthenticationExtension

from access.permissions import NOT_AUTHENTICATED

AUTH_ERROR = "AuthError"
AUTH_RESPONSES = {
    "401": (
        "No usable credentials: the Authorization: Bearer header is missing, or its token is unknown, "
        "revoked or expired.",
        {"detail": NOT_AUTHENTICATED},
    ),
    "403": (
        "The credentials may not do this: a read-only token writing, a session of a user who is not staff, "
        "or a session write without its CSRF token.",
        {"detail": 'The token "dashboard" is read-only: it may not POST.'},
    ),
}


class BearerTokenScheme(OpenApiAuthenticationExtension):
    target_class = "access.authentication.BearerTokenAuthentication"
    name = "bearerAuth"

    def get_security_definition(self, auto_schema: Any) -> dict[str, str]:
        return {
            "type": "http",
            "scheme": "bearer",
            "description": "An API token (`python manage.py api_token create NAME`).",
        }

    def get_security_requirement(self, auto_schema: Any) -> dict[str, list[str]] | None:
        return super().get_security_requirement(auto_schema) if settings.API_AUTH else None


class StaffSessionScheme(SessionScheme):
    target_class = "access.authentication.StaffSessionAuthentication"
    priority = 0

    def get_security_requirement(self, auto_schema: Any) -> dict[str, list[str]] | None:
        return super().get_security_requirement(auto_schema) if settings.API_AUTH else None


def add_auth_responses(result: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
    """drf-spectacular postprocessing hook: every operation that needs credentials declares its 401 and
    403 (with the API's usual {"detail": "..."} body)."""
    protected = [
        operation
        for operations in result.get("paths", {}).values()
        for operation in operations.values()
        if operation.get("security")
    ]
    if not protected:
        return result
    result.setdefault("components", {}).setdefault("schemas", {})[AUTH_ERROR] = {
        "type": "object",
        "properties": {"detail": {"type": "string"}},
        "required": ["detail"],
    }
    for operation in protected:
        for status, (description, example) in AUTH_RESPONSES.items():
            operation["responses"].setdefault(
                status,
                {
                    "description": description,
                    "content": {
                        "application/json": {
                            "schema": {"$ref": f"#/components/schemas/{AUTH_ERROR}"},
                            "examples": {status: {"value": example}},
                        }
                    },
                },
            )
    return result
