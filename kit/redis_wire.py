"""Redis round trips on a connection the calling thread owns, past redis-py's pipeline and pool.

redis-py 8's pipeline and pool spend as much CPU per round trip on their bookkeeping (retry closures,
observability hooks, the pool's checkout with its readiness poll, response callbacks) as the round trip's
own work (bench/HISTORY.md), and the bridge, every step and every Celery task's acknowledgement make round
trips all the time. Imports only redis: the Celery broker's transport (`kit.broker`) uses it too.
"""

import os
import threading
import weakref
from typing import Any

import redis

Command = tuple[Any, ...]

_thread_local = threading.local()


def round_trip(pool: redis.ConnectionPool, commands: list[Command]) -> list[Any]:
    """Send `commands` at once on this thread's connection to `pool`'s Redis and read their replies, an
    error reply in its place. A connection error is tried once more on a new connection, as redis-py
    would (a Redis restart leaves connections dead)."""
    connection = _thread_connection(pool)
    try:
        try:
            return _send_and_read(connection, commands)
        except (redis.exceptions.ConnectionError, redis.exceptions.TimeoutError):
            connection.disconnect()
            return _send_and_read(connection, commands)  # connects again
    except BaseException:
        connection.disconnect()  # replies may be left unread: the connection must not be used again
        raise


def _thread_connection(pool: redis.ConnectionPool) -> redis.connection.AbstractConnection:
    """This thread's own connection with `pool`'s parameters (one per pool: a thread may talk to two
    Redis databases); a forked child makes its own."""
    owned = getattr(_thread_local, "owned", None)
    if owned is None or owned[0] != os.getpid():
        owned = _thread_local.owned = (os.getpid(), weakref.WeakKeyDictionary())
    connections = owned[1]
    connection = connections.get(pool)
    if connection is None:
        connection = connections[pool] = pool.connection_class(**pool.connection_kwargs)
    return connection


def _send_and_read(connection: redis.connection.AbstractConnection, commands: list[Command]) -> list[Any]:
    connection.send_packed_command(connection.pack_commands(commands))
    replies: list[Any] = []
    for _ in commands:
        try:
            replies.append(connection.read_response())
        except redis.exceptions.ResponseError as error:
            replies.append(error)
    return replies
