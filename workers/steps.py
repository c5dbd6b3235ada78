"""Requesting dispatch steps: at most one queued step per robot, however many wake-ups arrive.

A requested step runs on a bridge's step threads while one listens (`take_requested`), else on a Celery
worker. A Celery task costs the requester and the worker more than the step itself, and at a few hundred
starts a second the one worker queued them for seconds; a bridge takes requests off a Redis list with
one round trip per batch. The bridges renew `LISTENING` while they listen, so when none runs the requests
go to Celery again within `LISTENING_SECONDS`.
"""

import logging
import threading
import time
from collections.abc import Iterable
from functools import cache

import kombu.exceptions
import redis

from workers import livestate

logger = logging.getLogger(__name__)

# A queued-step marker expires on its own, so a step lost with a killed worker cannot block later ones.
STEP_MARKER_SECONDS = 10
REQUESTED = f"{livestate.PREFIX}:step-requests"  # "name at" entries the bridges' step threads take
LISTENING = f"{livestate.PREFIX}:step-listening"  # exists while a bridge takes requested steps
LISTENING_SECONDS = 3
TAKE_COUNT = 500  # requests taken per round trip

# A step request that could not be queued (Redis or the broker away) is tried again this often.
UNQUEUED_RETRY_SECONDS = 1.0

# Marks each robot's step queued unless it already is; queues the marked ones on REQUESTED while a bridge
# listens and returns the marked ones left for a Celery worker.
# KEYS: LISTENING, REQUESTED, then one marker per robot. ARGV: marker TTL, at, names.
_REQUEST = """
local to_bridges = redis.call('EXISTS', KEYS[1]) == 1
local for_workers = {}
for i = 3, #KEYS do
  local name = ARGV[i]
  if redis.call('SET', KEYS[i], 1, 'NX', 'EX', ARGV[1]) then
    if to_bridges then
      redis.call('RPUSH', KEYS[2], name .. ' ' .. ARGV[2])
    else
      table.insert(for_workers, name)
    end
  end
end
return for_workers
"""


def step_marker_key(name: str) -> str:
    return f"{livestate.PREFIX}:step-queued:{name}"


@cache
def _request_script() -> redis.commands.core.Script:
    return livestate.client().register_script(_REQUEST)


def request_steps(names: Iterable[str], *, at: float | None = None) -> None:
    """Queue a step for each robot that has none queued yet; `at` is when the cause happened (epoch s)."""
    names = list(names)
    if not names:
        return
    at = time.time() if at is None else at
    keys = [LISTENING, REQUESTED, *(step_marker_key(name) for name in names)]
    for_workers = _request_script()(keys=keys, args=[STEP_MARKER_SECONDS, repr(at), *names])
    if for_workers:
        from workers.tasks import step_robot  # tasks import services, which import this module

        for name in for_workers:
            step_robot.delay(name.decode(), at)


def take_requested(timeout: int = 1) -> list[tuple[str, float]]:
    """Say this process listens, wait up to `timeout` s for requested steps and take them: (robot, at)
    pairs, their markers cleared (a wake-up after this queues another step)."""
    pipe = livestate.client().pipeline(transaction=False)
    pipe.set(LISTENING, 1, ex=LISTENING_SECONDS)
    pipe.blmpop(timeout, 1, REQUESTED, direction="LEFT", count=TAKE_COUNT)
    popped = pipe.execute()[1]
    if not popped:
        return []
    requests = [entry.decode().rsplit(" ", 1) for entry in popped[1]]
    livestate.client().delete(*{step_marker_key(name) for name, _ in requests})
    return [(name, float(at)) for name, at in requests]


def step_started(name: str) -> None:
    """Called before a step reads anything, so a change arriving during the step queues another one."""
    livestate.client().delete(step_marker_key(name))


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
