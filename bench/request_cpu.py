"""CPU per call of the API's hot requests and of a step request, measured in-process (no HTTP server,
no other load): what part of a process's CPU per order in the suite is Django and DRF, and what is
Celery's publishing. Run on a database of its own (it creates robots, missions and a token there):

    FLEET_DB_NAME=mission_dispatch_bench FLEET_REDIS_URL=redis://127.0.0.1:6379/3 \\
        .venv/bin/python -m bench.request_cpu --calls 500

Results and the machine's calibration figure: bench/HISTORY.md, "The full suite at a2d47bb".
"""

import argparse
import os
import time
from collections.abc import Callable

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
os.environ.setdefault("FLEET_SECRET_KEY", "request-cpu-" + "x" * 50)  # the settings refuse the built-in one
django.setup()

from django.conf import settings  # noqa: E402
from rest_framework.test import APIClient  # noqa: E402

from access.services import api_token_create  # noqa: E402
from bench.measure import cpu_speed_ms  # noqa: E402
from fleet.celery import app  # noqa: E402
from workers import step_requests  # noqa: E402

PREFIX = "request-cpu-"
ROBOTS = 200
WARMUP_CALLS = 50


def _cpu_ms_per_call(call: Callable[[int], object], calls: int) -> float:
    for index in range(WARMUP_CALLS):
        call(index)
    began = time.process_time()
    for index in range(calls):
        call(index)
    return (time.process_time() - began) / calls * 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=500)
    calls = parser.parse_args().calls
    settings.ALLOWED_HOSTS = ["*"]
    run = f"{PREFIX}{time.time_ns()}"
    _, key = api_token_create(name=run)
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Bearer {key}")
    robots = [f"{run}-{index}" for index in range(ROBOTS)]
    for name in robots:
        assert client.post("/robot", {"name": name}, format="json").status_code == 200

    def post_mission(index: int) -> None:
        body = {
            "robot": robots[index % ROBOTS],
            "name": f"{run}-m{time.time_ns()}",
            "mission_tree": [{"route": {"waypoints": [{"x": 1.0, "y": 2.0, "theta": 0.0}]}}],
        }
        assert client.post("/mission", body, format="json").status_code == 200

    def send_step_task(index: int) -> None:
        # to a queue no worker reads: the cost of publishing, not of stepping
        app.send_task(step_requests.STEP_TASK, ([robots[index % ROBOTS]], time.time()), queue=f"{run}-queue")

    print(f"calibration work: {cpu_speed_ms()} ms (lower is faster)")
    print(f"POST /mission: {_cpu_ms_per_call(post_mission, calls):.2f} ms CPU per call")
    get_robot = _cpu_ms_per_call(lambda index: client.get(f"/robot/{robots[index % ROBOTS]}"), calls)
    print(f"GET /robot/<name>: {get_robot:.2f} ms")
    print(f"send a step task (one robot): {_cpu_ms_per_call(send_step_task, calls):.3f} ms")
    app.connection_for_write().default_channel.queue_delete(f"{run}-queue")


if __name__ == "__main__":
    main()
