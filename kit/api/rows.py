"""Reading and locking the named object a request is about."""

from typing import TypeVar

from django.db.models import Model, QuerySet

from kit.api.errors import ObjectError
from kit.api.names import object_name_valid

M = TypeVar("M", bound=Model)


def object_get(queryset: QuerySet[M], *, alias: str, name: str, to_change: bool = False) -> M:
    """The object called `name`, or the reference's 400 (worded differently for PUT and DELETE). A name no
    object can have is not looked up: it may hold what PostgreSQL refuses in text (NUL)."""
    obj = queryset.filter(pk=name).first() if object_name_valid(name) else None
    if obj is None:
        raise ObjectError.not_found_to_change(name) if to_change else ObjectError.not_found(alias, name)
    return obj


def lock_row(obj: M) -> M:
    """`obj` re-read and locked until the transaction ends, so concurrent writers see each other's changes."""
    locked = type(obj)._default_manager.select_for_update().filter(pk=obj.pk).first()
    if locked is None:
        raise ObjectError.not_found_to_change(obj.pk)
    return locked
