"""What a caller may do: any usable token may read, a token that is not read-only may also write, and a
staff user's session may do both. Everything else is refused; FLEET_API_AUTH=off lets everything through."""

from django.conf import settings
from rest_framework.exceptions import NotAuthenticated, PermissionDenied
from rest_framework.permissions import SAFE_METHODS, BasePermission
from rest_framework.request import Request

from access.models import ApiToken

NOT_AUTHENTICATED = (
    "Authentication credentials were not provided: send the header Authorization: Bearer <token> "
    "(or log in to the admin as a staff user)."
)


class ApiAccess(BasePermission):
    def has_permission(self, request: Request, view: object) -> bool:
        if not settings.API_AUTH:
            return True
        token = request.auth
        if isinstance(token, ApiToken):
            if token.read_only and request.method not in SAFE_METHODS:
                raise PermissionDenied(f'The token "{token.name}" is read-only: it may not {request.method}.')
            return True
        user = request.user
        if user is not None and user.is_authenticated:
            if not user.is_staff:
                raise PermissionDenied("Only staff users may use the API through a session.")
            return True
        raise NotAuthenticated(NOT_AUTHENTICATED)
