"""Database parameters and transactions the project's plain-SQL hot paths share."""

import json
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import orjson
from django.db import connection, transaction
from psycopg.types.json import Jsonb


def jsonb(value: Any) -> Jsonb:
    """`value` as a jsonb parameter, serialized by orjson: Django's adapter uses the json module, which
    takes several times longer on a mission's tree and node status (the API's and the steps' hot paths)."""
    return Jsonb(value, dumps=_json_bytes)


def _json_bytes(value: Any) -> bytes:
    try:
        return orjson.dumps(value, option=orjson.OPT_NON_STR_KEYS)
    except orjson.JSONEncodeError:  # what orjson refuses and json takes: integers beyond 64 bits
        return json.dumps(value).encode()


@contextmanager
def pipelined_transaction() -> Iterator[None]:
    """A transaction block (`transaction.atomic`) whose statements psycopg sends in pipeline mode: a round
    trip for BEGIN (psycopg syncs after it), one for each fetch of results, and one for the writes with
    COMMIT, so a block that reads once and then writes costs three. Under load each round trip waits for a
    turn on the CPU, twice.

    The pipeline sits inside the block because psycopg syncs a pipeline, a round trip for nothing, at every
    change of autocommit, which the block makes on entry and on exit. COMMIT is sent in the pipeline, with
    the writes; the block's own commit then finds the transaction over and sends nothing (its on-commit
    hooks still run). Inside a caller's transaction, or one marked for rollback, the block ends as usual.
    """
    connection.ensure_connection()
    outermost = not connection.in_atomic_block
    with transaction.atomic(), connection.connection.pipeline():
        yield
        if outermost and not connection.needs_rollback:
            with connection.cursor() as cursor:
                cursor.execute("COMMIT")
