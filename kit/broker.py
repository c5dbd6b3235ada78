"""kombu's Redis transport as Celery's broker (`CELERY_BROKER_TRANSPORT`), with two changes to its channel
and one to its acknowledgement emulation.

Imports only kombu, redis and `kit.redis_wire`: kombu loads it by name when Celery first connects to the
broker.
"""

from collections.abc import Iterator
from contextlib import contextmanager
from time import time
from typing import Any

import kombu.transport.redis
import redis
from kombu.message import Message
from kombu.transport import virtual
from kombu.utils.json import dumps

from kit import redis_wire


class QoS(kombu.transport.redis.QoS):
    """kombu keeps each delivered task in Redis until it is acknowledged (so that a killed worker's tasks
    are delivered again): a write when the task arrives and one when it is done. Each is one round trip
    here, as kombu's transaction, on the thread's own connection: through redis-py's pipeline they cost
    twice the CPU, a tenth of a step worker's CPU per task (bench/HISTORY.md)."""

    def append(self, message: Message, delivery_tag: str) -> None:
        delivery = message.delivery_info
        entry = dumps([message._raw, delivery["exchange"], delivery["routing_key"]])
        self._transaction(
            ("ZADD", self.unacked_index_key, time(), delivery_tag),
            ("HSET", self.unacked_key, delivery_tag, entry),
        )
        virtual.QoS.append(self, message, delivery_tag)

    def ack(self, delivery_tag: str) -> None:
        self._transaction(
            ("ZREM", self.unacked_index_key, delivery_tag), ("HDEL", self.unacked_key, delivery_tag)
        )
        virtual.QoS.ack(self, delivery_tag)

    def _transaction(self, *commands: redis_wire.Command) -> None:
        replies = redis_wire.round_trip(self.channel.pool, [("MULTI",), *commands, ("EXEC",)])
        for reply in replies:
            if isinstance(reply, Exception):
                raise reply


class Channel(kombu.transport.redis.Channel):
    QoS = QoS
    _plain_client: redis.Redis | None = None

    @contextmanager
    def conn_or_acquire(self, client: redis.Redis | None = None) -> Iterator[redis.Redis]:
        """One client per connection pool, where kombu made a new one for every publish, delivery and
        acknowledgement: building a redis-py client (its response callbacks) was 7 % of a step worker's
        and of the bridge's CPU (bench/HISTORY.md). A client is thread-safe: each command takes a
        connection from the pool."""
        if client is not None:
            yield client
            return
        pool = self.pool
        plain = self._plain_client
        if plain is None or plain.connection_pool is not pool:
            plain = self._plain_client = self._create_client()
        yield plain

    def _connparams(self, asynchronous: bool = False) -> dict[str, Any]:
        """kombu 5.7, after Redis dropped the connection, still acts on channels whose connection it has
        torn down (restoring unacknowledged tasks when a channel closes, rejecting a message) and fails
        with an AttributeError ('NoneType' object has no attribute 'hostname' / 'client') that ends the
        worker ("Unrecoverable error", seen in the fault suite when Redis was killed while steps were in
        flight). As a connection error the same failure is one kombu handles: it reconnects, and tasks
        left unacknowledged are delivered again after the visibility timeout."""
        if self.connection is None or self.connection.client is None:
            raise redis.exceptions.ConnectionError("the broker connection is gone")
        return super()._connparams(asynchronous)


class Transport(kombu.transport.redis.Transport):
    Channel = Channel
