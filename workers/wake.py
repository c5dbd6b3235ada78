"""The one hook through which services ask the dispatch engine to step a robot."""

from django.db import transaction

from workers.steps import request_steps_or_later


def wake_robot(name: str) -> None:
    """Step robot `name` once the current transaction commits (so the worker sees the change); if Redis is
    away, once it is back: the change is committed, so the request that made it succeeds."""
    transaction.on_commit(lambda: request_steps_or_later([name]))
