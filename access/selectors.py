"""Reads of API tokens."""

import re
from datetime import timedelta

from django.db import connection
from django.db.models import QuerySet
from django.utils import timezone

from access.models import ApiToken

# What the key generator makes (`<prefix>.<secret>`, letters and digits); anything else is no token and
# never reaches the database.
TOKEN_PATTERN = re.compile(r"\A[A-Za-z0-9]{1,50}\.[A-Za-z0-9]{1,100}\Z")
# `last_used` is written at most this often per token, so authenticating costs no write per request.
LAST_USED_RESOLUTION = timedelta(minutes=1)
# Every request runs this lookup: one fixed statement on a plain cursor, its row made a model as the ORM
# makes one (`from_db`), because building the query with the ORM, or reading it through a raw queryset,
# cost more CPU than PostgreSQL spends running it (bench/README.md). `prefix` is unique.
TOKEN_FIELDS = [field.attname for field in ApiToken._meta.concrete_fields]
USABLE_TOKEN_BY_PREFIX = (
    f"SELECT {', '.join(field.column for field in ApiToken._meta.concrete_fields)} "
    f"FROM {ApiToken._meta.db_table} WHERE prefix = %s AND NOT revoked"
)


def api_token_list() -> QuerySet[ApiToken]:
    return ApiToken.objects.order_by("created", "name")


def api_token_for_key(key: str) -> ApiToken | None:
    """The usable token whose plaintext is `key` (not revoked, not expired), or None."""
    if not TOKEN_PATTERN.match(key):
        return None
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
