"""The Celery application shared by workers and beat (`celery -A fleet worker|beat`)."""

import functools
import logging
import os
from collections.abc import Callable
from typing import Any

import kombu.transport.redis
import redis
from celery import Celery
from celery.signals import task_prerun

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

logger = logging.getLogger(__name__)

app = Celery("fleet")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks()


@task_prerun.connect
def _replace_broken_connections(**kwargs: Any) -> None:
    """A task after a PostgreSQL restart gets a new connection instead of the dead one (CELERY_DB_REUSE_MAX
    keeps Celery's own fixup from closing connections)."""
    from fleet.db import drop_broken_connections  # Django's apps are loaded once tasks run

    drop_broken_connections()


def _restore_unacked_or_leave_it(restore: Callable[..., Any]) -> Callable[..., Any]:
    """kombu 5.7's Redis transport restores a channel's unacknowledged tasks when the channel closes, also
    after Redis dropped the connection, when the connection it would restore them on is already gone: the
    AttributeError ('NoneType' object has no attribute 'hostname') then ends the worker ("Unrecoverable
    error", seen in the fault suite when Redis was killed while steps were in flight). Those tasks stay in
    Redis's unacked set, and kombu delivers them again after the visibility timeout, so leaving them is safe.
    """

    @functools.wraps(restore)
    def restore_or_leave(self: Any, client: Any = None) -> Any:
        try:
            return restore(self, client)
        except (AttributeError, redis.RedisError, OSError) as error:
            logger.warning("unacknowledged tasks left to the visibility timeout (%r)", error)
            return None

    return restore_or_leave


kombu.transport.redis.QoS.restore_unacked = _restore_unacked_or_leave_it(
    kombu.transport.redis.QoS.restore_unacked
)
