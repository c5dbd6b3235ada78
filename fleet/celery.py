"""The Celery application shared by workers and beat (`celery -A fleet worker|beat`)."""

import os
from typing import Any

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
