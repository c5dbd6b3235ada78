"""The one hook through which services ask the dispatch engine to step a robot."""

from django.db import transaction


def wake_robot(name: str) -> None:
    """Step robot `name` once the current transaction commits (so the worker sees the change)."""
    transaction.on_commit(lambda: _enqueue_step(name))


def _enqueue_step(name: str) -> None:
    # The dispatch engine's step task is connected here (see workers/tasks.py).
    return None
