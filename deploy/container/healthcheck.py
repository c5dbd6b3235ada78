"""Health of one role's process in this container: exit 0 when healthy, 1 with the reason on stderr.

    python deploy/container/healthcheck.py ROLE   (the image: `health ROLE`)

- api: `GET /health` on its port answers 200.
- worker, notify: the Celery worker of this host (`steps@HOST`, `notify@HOST`, the names deploy/Procfile
  gives them) answers a ping through the broker.
- bridge, beat: PostgreSQL and Redis answer. These processes survive outages by themselves, so this is a
  readiness check: do not restart them on it (Kubernetes: no liveness probe; the process exits on what
  it cannot survive).
"""

import os
import socket
import sys
import urllib.request

TIMEOUT_SECONDS = 5.0


def api_health() -> None:
    port = int(os.environ.get("FLEET_API_PORT", 5000))
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=TIMEOUT_SECONDS) as response:
        if response.status != 200:
            raise RuntimeError(f"GET /health answered {response.status}")


def celery_ping(worker_prefix: str) -> None:
    from fleet.celery import app

    name = f"{worker_prefix}@{socket.gethostname()}"
    if not app.control.ping([name], timeout=TIMEOUT_SECONDS):
        raise RuntimeError(f"Celery worker {name} did not answer a ping")


def services_answer() -> None:
    import django

    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
    django.setup()
    from django.db import connection

    from robots import livestate

    with connection.cursor() as cursor:
        cursor.execute("SELECT 1")
    livestate.client().ping()


CHECKS = {
    "api": api_health,
    "worker": lambda: celery_ping("steps"),
    "notify": lambda: celery_ping("notify"),
    "bridge": services_answer,
    "beat": services_answer,
}


def main() -> int:
    if len(sys.argv) != 2 or sys.argv[1] not in CHECKS:
        print(f"usage: healthcheck.py ROLE; roles: {', '.join(CHECKS)}", file=sys.stderr)
        return 2
    try:
        CHECKS[sys.argv[1]]()
    except Exception as error:
        print(f"{sys.argv[1]} unhealthy: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
