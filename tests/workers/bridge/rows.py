"""Robot rows as a step in another process holds them."""

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from django.db import connection

from tests.database import other_connection


@contextmanager
def held(sql: str, params: list[Any]) -> Iterator[None]:
    """`sql` (a locking statement) run and its locks held by another connection, as a step holds its rows;
    in this test's connection a lock wait fails after 2 s instead of hanging the test."""
    other = other_connection()
    with connection.cursor() as cursor:
        cursor.execute("SET lock_timeout = '2s'")  # a flush that waits fails the test instead of hanging it
    try:
        other.execute(sql, params)
        yield
    finally:
        other.rollback()
        other.close()
        with connection.cursor() as cursor:
            cursor.execute("RESET lock_timeout")
