"""Object names: the alphabet every robot, mission and node name keeps to, and names made for a create."""

import base64
import uuid

from django.core.exceptions import ValidationError as DjangoValidationError
from django.core.validators import RegexValidator

from kit.api.errors import UsageError

# Names are MQTT topic levels and parts of VDA 5050 ids, so they keep to a safe alphabet.
OBJECT_NAME_MAX_LENGTH = 100
OBJECT_NAME_ALPHABET = "A-Z a-z 0-9 _ - . :"
object_name_validator = RegexValidator(
    r"\A[A-Za-z0-9_.:-]+\Z", message=f"Use only the characters {OBJECT_NAME_ALPHABET}.", code="invalid_name"
)
# base32 of a uuid4 without padding, as the reference generates names.
GENERATED_NAME_LENGTH = 26
# `<prefix>-<generated>` must still fit in a name.
NAME_PREFIX_MAX_LENGTH = OBJECT_NAME_MAX_LENGTH - GENERATED_NAME_LENGTH - 1


def object_name_check(name: str, *, what: str) -> None:
    """Raise a UsageError unless `name` is a valid name for a robot, mission or node (`what` names it)."""
    if len(name) > OBJECT_NAME_MAX_LENGTH:
        raise UsageError(f"{what} {name!r} is longer than {OBJECT_NAME_MAX_LENGTH} characters.")
    try:
        object_name_validator(name)
    except DjangoValidationError as error:
        raise UsageError(f"{what} {name!r} is invalid: {error.messages[0]}") from error


def object_name_for_create(*, name: str | None, prefix: str | None, what: str) -> str:
    """The name of a new object: `name`, `<prefix>-<random id>`, or a random id when neither is given."""
    if name is not None and prefix is not None:
        raise UsageError('Cannot have both "name" and "prefix"')
    if name is None:
        generated = base64.b32encode(uuid.uuid4().bytes).decode().rstrip("=").lower()
        name = generated if prefix is None else f"{prefix}-{generated}"
    object_name_check(name, what=what)
    return name


def object_name_valid(name: str) -> bool:
    return len(name) <= OBJECT_NAME_MAX_LENGTH and object_name_validator.regex.search(name) is not None
