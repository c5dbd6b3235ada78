"""The Celery worker against the real Redis broker: what kombu does when Redis drops its connection."""

import kombu
import pytest
from django.conf import settings

import fleet.celery  # noqa: F401  (installs the workaround tested here)


def test_unacknowledged_tasks_of_a_channel_whose_connection_is_gone_are_left_to_the_visibility_timeout(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """kombu restores them when the channel closes, on a connection that Redis dropped and kombu tore
    down: unpatched, the AttributeError ended the worker."""
    with kombu.Connection(settings.CELERY_BROKER_URL) as connection:
        channel = connection.default_channel
        channel.qos._delivered["an-unacknowledged-task"] = None
        transport, client = channel.connection, channel.connection.client
        channel._pool = None
        transport.client = None  # what the dropped connection left behind
        try:
            channel.qos.restore_unacked()
        finally:
            transport.client = client
            channel.qos._delivered.clear()

    assert "unacknowledged tasks left to the visibility timeout" in caplog.text
