"""Requesting dispatch steps: Celery tasks on the `steps` queue, at most one queued step per robot.

Whoever asks (the bridge for a state that changed what the engine reads, the API for a change of a
mission or robot, beat for time that passed) goes through `request_steps`. A robot whose step is already
queued gets no second one; its marker is cleared when its step reads the robot's state
(`fleet.livestate.state_for_step`), so a change that arrives during the step queues one more. A task
carries several robots when a bridge batch or a sweep asks for several: Celery's cost per task is of the
order of a step's own.
"""

import logging
import threading
import time
from collections.abc import Iterable

import kombu.exceptions
import redis
from django.conf import settings

from fleet import livestate
from fleet.celery import app

logger = logging.getLogger(__name__)

STEP_TASK = "fleet.step_robots"  # workers.tasks.step_robots, sent by name: the tasks import this module
# A queued-step marker expires on its own, so a step lost with a killed worker cannot block later ones.
STEP_MARKER_SECONDS = 10
# A step request that could not be queued (Redis or the broker away) is tried again this often.
UNQUEUED_RETRY_SECONDS = 1.0


def request_steps(names: Iterable[str], *, at: float | None = None) -> None:
    """Queue a step for each robot that has none queued yet; `at` is when the cause happened (epoch s).

    One Redis round trip marks them, one Celery task per `STEP_TASK_ROBOTS` of them carries them."""
    names = list(dict.fromkeys(names))
    if not names:
        return
    at = time.time() if at is None else at
    marked = livestate.round_trip(
        [("SET", livestate.step_marker_key(name), 1, "NX", "EX", STEP_MARKER_SECONDS) for name in names]
    )
    for reply in marked:
        if isinstance(reply, Exception):
            raise reply
    queued = [name for name, reply in zip(names, marked, strict=True) if reply is not None]
    if not queued:
        return
    size = settings.STEP_TASK_ROBOTS
    for start in range(0, len(queued), size):
        try:
            app.send_task(STEP_TASK, (queued[start : start + size], at), queue=settings.STEP_QUEUE)
        except Exception:
            # Unmarked, so that asking again queues them: a marker without its task would block them.
            livestate.round_trip([("DEL", *(livestate.step_marker_key(name) for name in queued[start:]))])
            raise


def request_steps_or_later(names: Iterable[str]) -> None:
    """`request_steps`, or if Redis or the broker is away, the same again in the background until it works.

    For callers whose change is committed already (an API request, beat's heartbeat check): the change
    stands whether or not its step can be queued now, so the caller must not fail for it.
    """
    names = list(names)
    try:
        request_steps(names)
    except (redis.RedisError, kombu.exceptions.OperationalError, OSError) as error:
        logger.warning(
            "steps of %s not queued (%s); trying again every %s s", names, error, UNQUEUED_RETRY_SECONDS
        )
        _unqueued.add(names)


class _Unqueued:
    """Robots whose step request failed, requested again by a thread of their own until Redis is back."""

    def __init__(self) -> None:
        self._names: set[str] = set()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def add(self, names: list[str]) -> None:
        with self._lock:
            self._names.update(names)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(
                    target=self._retry_until_queued, name="unqueued-steps", daemon=True
                )
                self._thread.start()

    def _retry_until_queued(self) -> None:
        while True:
            time.sleep(UNQUEUED_RETRY_SECONDS)
            with self._lock:
                names, self._names = self._names, set()
            try:
                request_steps(names)
            except (redis.RedisError, kombu.exceptions.OperationalError, OSError):
                with self._lock:
                    self._names |= names
                continue
            logger.info("steps of %s queued after all", sorted(names))
            with self._lock:
                if not self._names:
                    self._thread = None
                    return


_unqueued = _Unqueued()
