"""Reads of API tokens, and whether what a request authenticated with is still usable."""

import re
import threading
import time
from collections.abc import Collection
from dataclasses import dataclass
from datetime import timedelta

from django.conf import settings
from django.contrib.auth import HASH_SESSION_KEY, get_user_model
from django.contrib.auth.base_user import AbstractBaseUser
from django.contrib.sessions.models import Session
from django.db import connection
from django.db.models import QuerySet
from django.utils import timezone
from django.utils.crypto import constant_time_compare
from rest_framework.request import Request

from access.models import ApiToken

# What the key generator makes (`<prefix>.<secret>`, letters and digits); anything else is no token and
# never reaches the database.
TOKEN_PATTERN = re.compile(r"\A[A-Za-z0-9]{1,50}\.[A-Za-z0-9]{1,100}\Z")
# `last_used` is written at most this often per token, so authenticating costs no write per request.
LAST_USED_RESOLUTION = timedelta(minutes=1)
# Every request runs this lookup: one fixed statement on a plain cursor, its row made a model as the ORM
# makes one (`from_db`), because building the query with the ORM, or reading it through a raw queryset,
# cost more CPU than PostgreSQL spends running it (bench/HISTORY.md). `prefix` is unique.
TOKEN_FIELDS = [field.attname for field in ApiToken._meta.concrete_fields]
USABLE_TOKEN_BY_PREFIX = (
    f"SELECT {', '.join(field.column for field in ApiToken._meta.concrete_fields)} "
    f"FROM {ApiToken._meta.db_table} WHERE prefix = %s AND NOT revoked"
)


def api_token_list() -> QuerySet[ApiToken]:
    return ApiToken.objects.order_by("created", "name")


# Tokens this process found usable: plaintext -> (monotonic s until which it is taken as usable, token).
# A few per client, so the bound only keeps made-up traffic from growing it.
_usable: dict[str, tuple[float, ApiToken]] = {}
_USABLE_MAX = 1000
_usable_lock = threading.Lock()


def api_token_for_key(key: str) -> ApiToken | None:
    """The usable token whose plaintext is `key` (not revoked, not expired), or None. A token found usable
    is taken as such by this process for `API_TOKEN_CACHE_SECONDS` (its expiry still checked)."""
    if not TOKEN_PATTERN.match(key):
        return None
    now = time.monotonic()
    cached = _usable.get(key)
    if cached is not None and now < cached[0] and not cached[1].has_expired:
        return cached[1]
    token = _api_token_looked_up(key)
    with _usable_lock:
        if token is None or settings.API_TOKEN_CACHE_SECONDS <= 0:
            _usable.pop(key, None)
        else:
            if len(_usable) >= _USABLE_MAX:
                _usable.clear()
            _usable[key] = (now + settings.API_TOKEN_CACHE_SECONDS, token)
    return token


def api_tokens_forget() -> None:
    """Look every token up again (this process revoked one)."""
    with _usable_lock:
        _usable.clear()


def _api_token_looked_up(key: str) -> ApiToken | None:
    prefix, _, _ = key.partition(".")
    with connection.cursor() as cursor:
        cursor.execute(USABLE_TOKEN_BY_PREFIX, [prefix])
        row = cursor.fetchone()
    token = None if row is None else ApiToken.from_db(connection.alias, TOKEN_FIELDS, row)
    if token is None or not token.is_valid(key) or token.has_expired:
        return None
    now = timezone.now()
    if token.last_used is None or now - token.last_used >= LAST_USED_RESOLUTION:
        ApiToken.objects.filter(pk=token.pk).update(last_used=now)
        token.last_used = now
    return token


@dataclass(frozen=True)
class Credential:
    """What a request authenticated with, to be checked again while what it opened lasts (a stream): a
    token, or a staff user's session with the session's hash of the user's password."""

    token_id: str | None = None
    session_key: str | None = None
    user_id: str | None = None
    session_hash: str = ""


def request_credential(request: Request) -> Credential | None:
    """The request's credential; None when it needed none (FLEET_API_AUTH off)."""
    token = request.auth
    if isinstance(token, ApiToken):
        return Credential(token_id=token.pk)
    user = request.user
    if user is not None and user.is_authenticated and request.session.session_key:
        return Credential(
            session_key=request.session.session_key,
            user_id=str(user.pk),
            session_hash=request.session.get(HASH_SESSION_KEY, ""),
        )
    return None


def credentials_usable(credentials: Collection[Credential]) -> set[Credential]:
    """Those of `credentials` that would still authenticate a request: the token not revoked or expired;
    the session not ended or expired, its user still an active staff user (ApiAccess admits no other
    session) whose password has not changed since the login: the session's hash checked as Django's
    `get_user` checks it, under SECRET_KEY or one of SECRET_KEY_FALLBACKS, but without its writes (it
    would end or re-key the operator's session). Three queries at most, however many credentials."""
    now = timezone.now()
    token_ids = {credential.token_id for credential in credentials if credential.token_id}
    usable_tokens = {
        token.pk
        for token in ApiToken.objects.get_usable_keys().filter(pk__in=token_ids)
        if not token.has_expired  # the library's own test, as authentication (`api_token_for_key`) uses
    }
    sessions = [credential for credential in credentials if credential.session_key]
    live_sessions = set(
        Session.objects.filter(
            session_key__in={credential.session_key for credential in sessions}, expire_date__gt=now
        ).values_list("session_key", flat=True)
    )
    users = {
        str(user.pk): user
        for user in get_user_model().objects.filter(
            pk__in={credential.user_id for credential in sessions}, is_active=True, is_staff=True
        )
    }
    usable = {credential for credential in credentials if credential.token_id in usable_tokens}
    for credential in sessions:
        user = users.get(credential.user_id or "")
        if credential.session_key in live_sessions and user is not None and _hash_holds(credential, user):
            usable.add(credential)
    return usable


def _hash_holds(credential: Credential, user: AbstractBaseUser) -> bool:
    hashes = [user.get_session_auth_hash(), *user.get_session_auth_fallback_hash()]
    return any(constant_time_compare(credential.session_hash, each) for each in hashes)
