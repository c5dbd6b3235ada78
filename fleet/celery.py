"""The Celery application shared by workers and beat (`celery -A fleet worker|beat`)."""

import functools
import os
from collections.abc import Callable
from typing import Any

import kombu.transport.redis
import redis
from celery import Celery
from celery.signals import task_prerun

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

app = Celery("fleet")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks()


@task_prerun.connect
def _replace_broken_connections(**kwargs: Any) -> None:
    """A task after a PostgreSQL restart gets a new connection instead of the dead one (CELERY_DB_REUSE_MAX
    keeps Celery's own fixup from closing connections)."""
    from fleet.db import drop_broken_connections  # Django's apps are loaded once tasks run

    drop_broken_connections()


def _connparams_or_connection_error(connparams: Callable[..., Any]) -> Callable[..., Any]:
    """kombu 5.7's Redis transport, after Redis dropped the connection, still acts on channels whose
    connection it has torn down (restoring unacknowledged tasks when a channel closes, rejecting a message)
    and fails with an AttributeError ('NoneType' object has no attribute 'hostname' / 'client') that ends
    the worker ("Unrecoverable error", seen in the fault suite when Redis was killed while steps were in
    flight). As a connection error the same failure is one kombu handles: it reconnects, and tasks left
    unacknowledged are delivered again after the visibility timeout."""

    @functools.wraps(connparams)
    def connparams_or_connection_error(self: Any, asynchronous: bool = False) -> Any:
        if self.connection is None or self.connection.client is None:
            raise redis.exceptions.ConnectionError("the broker connection is gone")
        return connparams(self, asynchronous)

    return connparams_or_connection_error


kombu.transport.redis.Channel._connparams = _connparams_or_connection_error(
    kombu.transport.redis.Channel._connparams
)
