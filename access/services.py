"""Changes to API tokens, and the record of who made each write (called by the robot and mission services
inside their own transaction)."""

import os
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from django.db import IntegrityError, transaction

from access.choices import WriteAction
from access.models import TOKEN_NAME_MAX_LENGTH, ApiToken, WriteRecord
from access.selectors import api_token_for_key, api_tokens_forget
from kit.api.errors import UsageError

# The token `make run` keeps for the developer (`api_token dev`).
DEV_TOKEN_NAME = "development"


def api_token_create(*, name: str, read_only: bool = False) -> tuple[ApiToken, str]:
    """A new token and its plaintext, which is stored nowhere (only its SHA-512 hash is)."""
    name = name.strip()
    if not name or len(name) > TOKEN_NAME_MAX_LENGTH:
        raise UsageError(f"A token name has 1 to {TOKEN_NAME_MAX_LENGTH} characters.")
    try:
        with transaction.atomic():
            return ApiToken.objects.create_key(name=name, read_only=read_only)
    except IntegrityError as error:
        raise UsageError(
            f'A token named "{name}" already exists; revoke it first or pick another name.'
        ) from error


def api_token_revoke(*, name: str) -> ApiToken:
    """Revoke the usable token called `name`: it is refused from now on (this cannot be undone)."""
    with transaction.atomic():
        token = ApiToken.objects.select_for_update().filter(name=name, revoked=False).first()
        if token is None:
            raise UsageError(f'No usable token named "{name}": it does not exist or is revoked already.')
        token.revoked = True
        token.save(update_fields=["revoked"])
    api_tokens_forget()  # refused by this process at once; by the others within API_TOKEN_CACHE_SECONDS
    return token


def dev_token_ensure(*, path: Path) -> str:
    """The development token's plaintext, kept in `path` (git-ignored): the one stored there while it is
    still usable, else a new one (replacing any earlier development token)."""
    if path.exists():
        key = path.read_text().strip()
        if api_token_for_key(key) is not None:
            return key
    with transaction.atomic():
        if ApiToken.objects.filter(name=DEV_TOKEN_NAME, revoked=False).exists():
            api_token_revoke(name=DEV_TOKEN_NAME)
        _, key = api_token_create(name=DEV_TOKEN_NAME)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "w") as file:
        file.write(key + "\n")
    return key


# What the writes recorded in this context came through (WriteRecord.via), set by `writes_via`.
_WRITES_VIA: ContextVar[str] = ContextVar("writes_via", default="")


@contextmanager
def writes_via(via: str) -> Iterator[None]:
    """The write records made inside are marked as coming through `via` (the MCP server's tools call the
    same services as the API, which need not know who calls them)."""
    reset = _WRITES_VIA.set(via)
    try:
        yield
    finally:
        _WRITES_VIA.reset(reset)


def writes_via_now() -> str:
    """What the writes made now come through (WriteRecord.via), for a write recorded in plain SQL."""
    return _WRITES_VIA.get()


def write_record(*, actor: str, action: WriteAction, object_name: str) -> WriteRecord:
    """Record a write; call it inside the write's transaction, so both are stored or neither."""
    via = writes_via_now()
    return WriteRecord.objects.create(actor=actor, action=action, object_name=object_name, via=via)
