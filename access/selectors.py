"""Reads of API tokens."""

import re
from datetime import timedelta

from django.db.models import QuerySet
from django.utils import timezone

from access.models import ApiToken

# What the key generator makes (`<prefix>.<secret>`, letters and digits); anything else is no token and
# never reaches the database.
TOKEN_PATTERN = re.compile(r"\A[A-Za-z0-9]{1,50}\.[A-Za-z0-9]{1,100}\Z")
# `last_used` is written at most this often per token, so authenticating costs no write per request.
LAST_USED_RESOLUTION = timedelta(minutes=1)


def api_token_list() -> QuerySet[ApiToken]:
    return ApiToken.objects.order_by("created", "name")


def api_token_for_key(key: str) -> ApiToken | None:
    """The usable token whose plaintext is `key` (not revoked, not expired), or None."""
    if not TOKEN_PATTERN.match(key):
        return None
    try:
        token = ApiToken.objects.get_from_key(key)
    except ApiToken.DoesNotExist:
        return None
    if token.has_expired:
        return None
    now = timezone.now()
    if token.last_used is None or now - token.last_used >= LAST_USED_RESOLUTION:
        ApiToken.objects.filter(pk=token.pk).update(last_used=now)
        token.last_used = now
    return token
