"""The Celery application shared by workers and beat (`celery -A fleet worker|beat`)."""

import os
from typing import Any

from celery import Celery
from celery.signals import task_prerun

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

app = Celery("fleet")
app.config_from_object("fleet.celery:celery_settings", namespace="CELERY")
app.autodiscover_tasks()


def __getattr__(name: str) -> Any:
    """`celery_settings`: Django's CELERY_ settings copied into a dict when Celery first reads its
    configuration. Celery looks it up several times for every task it sends or receives, and each look
    through Django's lazy settings object cost more than a dict's (bench/HISTORY.md)."""
    if name == "celery_settings":
        from django.conf import settings

        return {key: getattr(settings, key) for key in dir(settings) if key.startswith("CELERY_")}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@task_prerun.connect
def _replace_broken_connections(**kwargs: Any) -> None:
    """A task after a PostgreSQL restart gets a new connection instead of the dead one (CELERY_DB_REUSE_MAX
    keeps Celery's own fixup from closing connections)."""
    from kit.db import drop_broken_connections  # Django's apps are loaded once tasks run

    drop_broken_connections()
