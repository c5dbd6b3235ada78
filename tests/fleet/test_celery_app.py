"""The Celery app reads its configuration from a dict of Django's CELERY_ settings (`fleet.celery`), not
through Django's lazy settings object: a Celery that resolved `config_from_object`'s "module:attribute"
differently, or stopped stripping the namespace, would run on its defaults, which these tests catch."""

from django.conf import settings

from fleet import celery


def test_celery_reads_the_projects_settings_from_the_copied_dict() -> None:
    assert celery.app.conf.broker_url == settings.CELERY_BROKER_URL
    assert celery.app.conf.task_acks_late is True
    assert celery.app.conf.task_default_queue == settings.STEP_QUEUE
    assert celery.app.conf.worker_prefetch_multiplier == settings.CELERY_WORKER_PREFETCH_MULTIPLIER
    assert set(celery.app.conf.beat_schedule) == set(settings.CELERY_BEAT_SCHEDULE)


def test_the_copy_is_a_plain_dict_of_every_celery_setting() -> None:
    copied = celery.celery_settings
    assert type(copied) is dict
    assert copied == {key: getattr(settings, key) for key in dir(settings) if key.startswith("CELERY_")}


def test_the_broker_is_the_projects_transport() -> None:
    transport = celery.app.connection_for_write().transport
    assert type(transport).__module__ == "kit.broker"
