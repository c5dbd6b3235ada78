"""What the long-lived processes (the bridge, the step workers) share: waiting out PostgreSQL or Redis at
their start, the backoff of what they try again (`retry_delay`, also the step task's), and settling once
started."""

import gc
import logging
import sys
import time
from collections.abc import Callable

from kit.db import drop_broken_connections
from workers import tuning

logger = logging.getLogger(__name__)


def retry_delay(failures: int) -> float:
    """Seconds before the next try of what failed `failures` times in a row."""
    return min(tuning.RETRY_MAX_SECONDS, tuning.RETRY_FIRST_SECONDS * 2 ** (failures - 1))


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
    every few seconds (bench/HISTORY.md has how long). The short switch interval is for the threads that
    wait on round trips.
    """
    gc.freeze()
    sys.setswitchinterval(tuning.SWITCH_INTERVAL_SECONDS)
