"""Who is calling the REST API: a bearer token (`Authorization: Bearer <token>`) or a staff user's session
(the admin's login, CSRF enforced). Both step aside when FLEET_API_AUTH is off (the reference's open API);
they read the setting per request, so tests can switch it."""

from django.conf import settings
from django.http import HttpRequest
from rest_framework.authentication import BaseAuthentication, SessionAuthentication, get_authorization_header
from rest_framework.exceptions import AuthenticationFailed
from rest_framework.request import Request

from access.choices import ANONYMOUS, token_actor, user_actor
from access.models import ApiToken
from access.selectors import api_token_for_key

BEARER = "Bearer"


class BearerTokenAuthentication(BaseAuthentication):
    """`Authorization: Bearer <token>`; a token that is unknown, revoked or expired is a 401."""

    def authenticate(self, request: Request) -> tuple[None, ApiToken] | None:
        if not settings.API_AUTH:
            return None
        scheme, _, key = get_authorization_header(request).decode("latin-1").partition(" ")
        if scheme.lower() != BEARER.lower():
            return None
        token = api_token_for_key(key.strip())
        if token is None:
            raise AuthenticationFailed("Invalid token: unknown, revoked or expired.", code="invalid_token")
        # A token is no Django user: who it is travels as request.auth.
        return None, token

    def authenticate_header(self, request: Request) -> str:
        return f'{BEARER} realm="api"'


class StaffSessionAuthentication(SessionAuthentication):
    """The admin's session, with Django's CSRF check on writes (ApiAccess admits only staff users)."""

    def authenticate(self, request: Request) -> tuple[object, None] | None:
        if not settings.API_AUTH:
            return None
        return super().authenticate(request)


def request_actor(request: Request | HttpRequest) -> str:
    """Who makes a write (WriteRecord.actor): the token's name, the user's name, or anonymous (open mode)."""
    token = getattr(request, "auth", None)
    if isinstance(token, ApiToken):
        return token_actor(token.name)
    user = getattr(request, "user", None)
    if user is not None and user.is_authenticated:
        return user_actor(user.get_username())
    return ANONYMOUS
