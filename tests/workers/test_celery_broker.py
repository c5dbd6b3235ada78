"""The Celery worker against the real Redis broker: what kombu does when Redis drops its connection."""

import kombu
import pytest
import redis
from django.conf import settings

import fleet.celery  # noqa: F401  (installs the workaround tested here)


@pytest.mark.parametrize("torn_down", ["client", "connection"])
def test_a_channel_whose_connection_is_gone_fails_as_a_connection_error(torn_down: str) -> None:
    """kombu restores unacknowledged tasks and rejects messages on channels whose connection Redis dropped
    and kombu tore down: unpatched, an AttributeError ended the worker; a connection error is one kombu
    handles (it reconnects)."""
    with kombu.Connection(settings.CELERY_BROKER_URL) as connection:
        channel = connection.default_channel
        channel.qos._delivered["an-unacknowledged-task"] = None
        transport, client = channel.connection, channel.connection.client
        channel._pool = None
        if torn_down == "client":
            transport.client = None
        else:
            channel.connection = None
        try:
            with pytest.raises(redis.exceptions.ConnectionError, match="the broker connection is gone"):
                channel.qos.restore_unacked()
        finally:
            channel.connection, transport.client = transport, client
            channel.qos._delivered.clear()
