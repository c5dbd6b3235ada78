"""Database parameters and transactions the project's plain-SQL hot paths share."""

import json
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import orjson
from django.db import connection, connections, transaction
from psycopg.pq import TransactionStatus
from psycopg.types.json import Jsonb


def jsonb(value: Any) -> Jsonb:
    """`value` as a jsonb parameter, serialized by orjson: Django's adapter uses the json module, which
    takes several times longer on a mission's tree and node status (the API's and the steps' hot paths)."""
    return Jsonb(value, dumps=_json_bytes)


def json_column(value: Any) -> Any:
    """A JSON column read by plain SQL: Django leaves it undecoded."""
    return orjson.loads(value) if isinstance(value, str | bytes) else value


def _json_bytes(value: Any) -> bytes:
    try:
        return orjson.dumps(value, option=orjson.OPT_NON_STR_KEYS)
    except orjson.JSONEncodeError:  # what orjson refuses and json takes: integers beyond 64 bits
        return json.dumps(value).encode()


@contextmanager
def pipelined_transaction() -> Iterator[None]:
    """A transaction whose statements psycopg sends in pipeline mode, BEGIN with the first of them: a
    block that reads once and then writes costs two round trips, one for BEGIN with the reads and one for
    the writes with COMMIT. Under load each round trip waits for a turn on the CPU, twice.

    Neither Django's transaction block nor psycopg's would do: each has psycopg sync the pipeline after
    BEGIN, a round trip for nothing. So the connection stays in autocommit mode and the block sends BEGIN
    and COMMIT itself, which Django does not see: inside it, on-commit hooks run at once and the ORM must
    not open a transaction block of its own (deletes and bulk writes do), so its writes are plain SQL.
    Inside a caller's transaction the block is a savepoint of it. A statement's error reaches PostgreSQL's
    reply only at the pipeline's sync, outside Django's cursor, so the block raises it as Django's error
    (an IntegrityError, say), as a cursor would.
    """
    connection.ensure_connection()
    if connection.in_atomic_block or not connection.get_autocommit():
        with transaction.atomic():
            yield
        return
    conn = connection.connection
    try:
        with connection.wrap_database_errors, connection.cursor() as cursor, conn.pipeline():
            cursor.execute("BEGIN")
            yield
            cursor.execute("COMMIT")
    except BaseException:
        # The pipeline's sync has reported the error; a failed statement made PostgreSQL skip the rest.
        if conn.pgconn.transaction_status in (TransactionStatus.INTRANS, TransactionStatus.INERROR):
            conn.execute("ROLLBACK")
        raise


def drop_broken_connections() -> None:
    """Close this thread's database connections on which a query failed and that no longer answer, so the
    next query connects again (PostgreSQL restarted, failed over, or dropped the connection).

    For the hot loops (the bridge, steps, Celery tasks), in place of Django's `close_old_connections`: with
    CONN_HEALTH_CHECKS on (for the API's requests) that pings the server before the next query every time.
    This asks the server only after an error, so a healthy connection costs nothing.
    """
    for conn in connections.all(initialized_only=True):
        if conn.connection is None or not conn.errors_occurred or conn.in_atomic_block:
            continue
        if conn.is_usable():
            conn.errors_occurred = False
        else:
            conn.close()
