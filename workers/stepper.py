"""Running one dispatch step with what it sends (`run_step`), for the Celery step tasks (`workers.tasks`).

A step takes the robot's row lock, so steps of one robot never interleave whichever worker runs them, and
it reads the robot's latest stored state, so a duplicate or late step finds nothing to do.
"""

import gc
import logging
import sys
import time
from collections.abc import Callable

from celery import current_app as app  # the roof's (fleet.celery), loaded with the settings
from django.conf import settings

from kit.db import drop_broken_connections
from missions.robot_step import robot_step
from robots import livestate
from workers import metrics
from workers.publish import publish

logger = logging.getLogger(__name__)

# A thread whose reply came in takes the interpreter lock back only when the thread holding it lets go:
# at Python's default 5 ms a reply waited up to that long behind one thread's Python code, after every
# round trip of a step (bench/README.md has what 0.5 ms did to step latency).
SWITCH_INTERVAL_SECONDS = 0.0005
NOTIFY_TASK = "fleet.run_notify"  # workers.tasks.run_notify, sent by name: the tasks import this module
# A failed step (PostgreSQL or Redis away) is tried again after this long, doubling per failure in a row.
RETRY_FIRST_SECONDS = 0.5
RETRY_MAX_SECONDS = 10.0


def retry_delay(failures: int) -> float:
    """Seconds before the next try of a step that failed `failures` times in a row."""
    return min(RETRY_MAX_SECONDS, RETRY_FIRST_SECONDS * 2 ** (failures - 1))


def keep_trying(what: str, action: Callable[[], None]) -> None:
    """Run `action` until it does not raise, with backoff: for what a process does once at its start and
    cannot do without PostgreSQL and Redis, which may be away just then."""
    failures = 0
    while True:
        try:
            action()
            return
        except Exception:
            failures += 1
            delay = retry_delay(failures)
            logger.warning("%s failed; trying again in %.1f s", what, delay, exc_info=failures == 1)
            drop_broken_connections()
            time.sleep(delay)


def settle_long_lived_process() -> None:
    """Set up a long-lived bridge or step-worker process once its startup is done.

    What is loaded by then (Django, the apps, the robot directory) lives as long as the process: frozen, it
    is out of the garbage collector's sight, whose full collections walked it and stopped the process
    every few seconds (bench/README.md has how long). The short switch interval is for the threads that
    wait on round trips.
    """
    gc.freeze()
    sys.setswitchinterval(SWITCH_INTERVAL_SECONDS)


def run_step(name: str, *, requested_at: float | None = None) -> None:
    """Step robot `name`, then send what the step decided and count what happened.

    `requested_at` (epoch s) is when the cause happened: the step latency metric counts from there."""
    outcome = robot_step(name=name)
    counters = livestate.client().pipeline(transaction=False)
    if requested_at is not None and outcome.messages:
        metrics.observe_step_latency(time.time() - requested_at, pipe=counters)
    metrics.count(metrics.ORDER_REJECTIONS, by=outcome.rejections, pipe=counters)
    for mission in outcome.finished:
        metrics.count(
            metrics.MISSIONS_FINISHED,
            pipe=counters,
            state=mission.state,
            failure_category=mission.failure_category or "",
        )
    if outcome.wire:
        assert outcome.address is not None  # a step sends messages only to a robot it found
        publish(name=name, address=outcome.address, messages=outcome.wire, counters=counters)
    livestate.execute(counters)  # after the messages are out: the step's metrics wait, its robot does not
    for mission, node in outcome.notifies:
        app.send_task(NOTIFY_TASK, (mission, node), queue=settings.NOTIFY_QUEUE)
