"""Database connections after PostgreSQL dropped them (a restart, a failover): the API's requests check
theirs first, the hot loops replace theirs after its first failure (`fleet.db.drop_broken_connections`)."""

from wsgiref.util import setup_testing_defaults

import pytest
from celery.signals import task_prerun
from django.db import OperationalError, connection

from fleet.wsgi import application
from robots.models import Robot
from tests.database import other_connection

pytestmark = pytest.mark.django_db(transaction=True)


def drop_backend() -> None:
    """End this connection's server process, as a PostgreSQL restart does."""
    pid = connection.connection.info.backend_pid
    with other_connection() as other:
        other.execute("SELECT pg_terminate_backend(%s)", [pid])


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


def wsgi_get(path: str, token: str) -> int:
    """GET `path` through the API's WSGI application, as its server calls it (Django's test client leaves
    out the connection handling this is about), with a bearer token; the response's status code."""
    environ: dict[str, object] = {
        "PATH_INFO": path,
        "REQUEST_METHOD": "GET",
        "HTTP_AUTHORIZATION": f"Bearer {token}",
    }
    setup_testing_defaults(environ)
    status: list[str] = []
    body = application(environ, lambda line, headers: status.append(line))
    b"".join(body)
    body.close()  # what the server does: request_finished
    return int(status[0].split()[0])


def test_an_api_request_after_postgresql_dropped_the_connection_succeeds(api_token: str) -> None:
    assert wsgi_get("/robot", api_token) == 200
    drop_backend()

    assert wsgi_get("/robot", api_token) == 200
