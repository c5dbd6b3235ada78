"""The one hook through which services ask the dispatch engine to step a robot."""

from django.db import transaction

from workers.steps import request_steps


def wake_robot(name: str) -> None:
    """Step robot `name` once the current transaction commits (so the worker sees the change)."""
    transaction.on_commit(lambda: request_steps([name]))
