"""Database connections after PostgreSQL dropped them (a restart, a failover): the API's requests check
theirs first (`kit.postgresql`), the hot loops replace theirs after its first failure
(`kit.db.drop_broken_connections`)."""

import asyncio
import time

import pytest
from celery.signals import task_prerun
from django.conf import settings
from django.db import OperationalError, connection

from fleet.asgi import application
from robots.models import Robot
from tests.database import other_connection

pytestmark = pytest.mark.django_db(transaction=True)


def drop_backend() -> None:
    """End this connection's server process, as a PostgreSQL restart does."""
    pid = connection.connection.info.backend_pid
    with other_connection() as other:
        other.execute("SELECT pg_terminate_backend(%s)", [pid])


def test_checking_an_idle_connection_sends_the_server_nothing() -> None:
    with connection.cursor() as cursor:
        cursor.execute("SELECT 'the last statement'")

    assert connection.is_usable()

    with other_connection() as other:
        (query,) = other.execute(
            "SELECT query FROM pg_stat_activity WHERE pid = %s", [connection.connection.info.backend_pid]
        ).fetchone()
    assert query == "SELECT 'the last statement'"


def test_a_connection_the_server_ended_is_found_unusable() -> None:
    Robot.objects.count()
    drop_backend()

    deadline = time.monotonic() + 5  # pg_terminate_backend only signals the server process
    while connection.is_usable():
        assert time.monotonic() < deadline, "the ended connection still counts as usable"
        time.sleep(0.05)

    connection.close_if_unusable_or_obsolete()  # what a request's start and first query do
    connection.close_if_health_check_failed()
    assert Robot.objects.count() >= 0


def test_a_dropped_connection_fails_once_then_is_replaced_before_the_next_task() -> None:
    Robot.objects.count()
    drop_backend()
    with pytest.raises(OperationalError):
        Robot.objects.count()

    task_prerun.send(sender=None)  # what a Celery worker sends before each task (fleet.celery)

    assert Robot.objects.count() >= 0
    assert not connection.errors_occurred


def test_a_healthy_connection_is_kept() -> None:
    Robot.objects.count()
    before = connection.connection

    task_prerun.send(sender=None)
    Robot.objects.count()

    assert connection.connection is before


def test_a_connection_that_failed_but_still_answers_is_kept() -> None:
    Robot.objects.count()
    before = connection.connection
    with pytest.raises(Exception, match="no_such_table"), connection.cursor() as cursor:
        cursor.execute("SELECT * FROM no_such_table")
    assert connection.errors_occurred

    task_prerun.send(sender=None)

    assert connection.connection is before
    assert not connection.errors_occurred


async def api_get(path: str, token: str) -> int:
    """GET `path` through the API's ASGI application, as its server calls it (Django's test client leaves
    out the connection handling this is about), with a bearer token; the response's status code."""
    sent: list[dict] = []
    body = iter([{"type": "http.request", "body": b"", "more_body": False}])

    async def receive() -> dict:
        for message in body:
            return message
        await asyncio.get_running_loop().create_future()  # then the client waits for the response
        raise AssertionError("unreachable")

    async def send(message: dict) -> None:
        sent.append(message)

    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": "GET",
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "root_path": "",
        "query_string": b"",
        "headers": [(b"host", b"testserver"), (b"authorization", f"Bearer {token}".encode())],
        "server": ("testserver", 80),
        "client": ("127.0.0.1", 50000),
    }
    await application(scope, receive, send)
    return sent[0]["status"]


def drop_other_backends(mine: int) -> None:
    """End the server processes of every connection to the test database but this test's (backend `mine`),
    as a PostgreSQL restart does: the API's request threads' connections."""
    with other_connection() as other:
        other.execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
            "WHERE datname = current_database() AND pid NOT IN (pg_backend_pid(), %s)",
            [mine],
        )


def test_api_requests_after_postgresql_dropped_their_connections_succeed(api_token: str) -> None:
    """Each of the API's request threads keeps its connection; each checks it before a request."""
    Robot.objects.count()
    mine = connection.connection.info.backend_pid

    async def requests() -> list[int]:
        statuses = [await api_get("/robot", api_token) for _ in range(settings.API_THREADS)]
        drop_other_backends(mine)
        return statuses + [await api_get("/robot", api_token) for _ in range(settings.API_THREADS)]

    try:
        assert asyncio.run(requests()) == [200] * 2 * settings.API_THREADS
    finally:
        drop_other_backends(mine)  # the threads' connections outlive the test: the test database goes
