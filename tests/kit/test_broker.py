"""The Celery worker against the real Redis broker: what kombu does when Redis drops its connection."""

import uuid

import kombu
import pytest
import redis
from django.conf import settings


@pytest.mark.parametrize("torn_down", ["client", "connection"])
def test_a_channel_whose_connection_is_gone_fails_as_a_connection_error(torn_down: str) -> None:
    """kombu restores unacknowledged tasks and rejects messages on channels whose connection Redis dropped
    and kombu tore down: unpatched, an AttributeError ended the worker; a connection error is one kombu
    handles (it reconnects)."""
    broker = kombu.Connection(settings.CELERY_BROKER_URL, transport=settings.CELERY_BROKER_TRANSPORT)
    with broker as connection:
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


def test_a_channel_publishes_and_acknowledges_through_one_client_per_pool() -> None:
    """Celery's connections use kit.broker's transport, whose channel reuses one Redis client (kombu made
    one per publish and acknowledgement); a new pool (after a reconnect) gets a new client."""
    from fleet.celery import app

    with app.connection_for_write() as connection:
        channel = connection.default_channel
        assert type(channel).__module__ == "kit.broker"
        with channel.conn_or_acquire() as first, channel.conn_or_acquire() as second:
            assert first is second
            assert first.ping()
        channel._pool = None
        with channel.conn_or_acquire() as third:
            assert third is not first
            assert third.connection_pool is channel.pool


def test_a_delivered_task_waits_in_redis_until_acknowledged_and_can_be_delivered_again_from_there() -> None:
    """kombu's acknowledgement emulation as kit.broker's QoS writes it: a delivered message is kept in
    Redis (what a killed worker's tasks are delivered again from) until it is acknowledged."""
    queue = f"test-qos-{uuid.uuid4().hex[:8]}"
    broker = kombu.Connection(settings.CELERY_BROKER_URL, transport=settings.CELERY_BROKER_TRANSPORT)
    with broker as connection, connection.SimpleQueue(queue) as simple:
        qos = simple.channel.qos
        assert type(qos).__module__ == "kit.broker"
        redis_client = simple.channel.client

        def kept(tag: str) -> tuple[bool, bool]:
            return (
                redis_client.hexists(qos.unacked_key, tag),
                redis_client.zscore(qos.unacked_index_key, tag) is not None,
            )

        try:
            simple.put({"robots": ["r1"]})
            first = simple.get(timeout=5)
            assert kept(first.delivery_tag) == (True, True)

            qos.restore_by_tag(first.delivery_tag)  # as after a worker was killed
            again = simple.get(timeout=5)
            assert again.payload == {"robots": ["r1"]}

            again.ack()
            assert kept(again.delivery_tag) == (False, False)
            assert redis_client.llen(queue) == 0
        finally:
            simple.channel.queue_delete(queue)
