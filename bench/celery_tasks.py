"""The task `bench.celery_worker` sends: a step's waiting without its work (loaded into the measured
workers with `celery worker -I bench.celery_tasks`)."""

import time

from fleet.celery import app
from robots import livestate

WAIT_TASK = "bench.wait"


@app.task(name=WAIT_TASK, ignore_result=True)
def wait(counter: str, milliseconds: float) -> None:
    """Wait as a step waits for PostgreSQL and Redis, without CPU; count the task done in Redis."""
    time.sleep(milliseconds / 1000)
    livestate.client().incr(counter)
