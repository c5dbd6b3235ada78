"""Requesting dispatch steps: at most one queued step per robot, however many wake-ups arrive.

A requested step runs on a bridge's step threads while one listens (`take_requested`), else on a Celery
worker. A Celery task costs the requester and the worker more than the step itself, and at a few hundred
starts a second the one worker queued them for seconds; a bridge takes requests off a Redis list with
one round trip per batch. The bridges renew `LISTENING` while they listen, so when none runs the requests
go to Celery again within `LISTENING_SECONDS`.
"""

import time
from collections.abc import Iterable
from functools import cache

import redis

from workers import livestate

# A queued-step marker expires on its own, so a step lost with a killed worker cannot block later ones.
STEP_MARKER_SECONDS = 10
REQUESTED = f"{livestate.PREFIX}:step-requests"  # "name at" entries the bridges' step threads take
LISTENING = f"{livestate.PREFIX}:step-listening"  # exists while a bridge takes requested steps
LISTENING_SECONDS = 3
TAKE_COUNT = 500  # requests taken per round trip

# Marks each robot's step queued unless it already is; queues the marked ones on REQUESTED while a bridge
# listens (and ARGV[1] does not ask for a worker) and returns the marked ones left for a Celery worker.
# KEYS: LISTENING, REQUESTED, then one marker per robot. ARGV: for workers (1/0), marker TTL, at, names.
_REQUEST = """
local to_bridges = ARGV[1] == '0' and redis.call('EXISTS', KEYS[1]) == 1
local for_workers = {}
for i = 3, #KEYS do
  local name = ARGV[i + 1]
  if redis.call('SET', KEYS[i], 1, 'NX', 'EX', ARGV[2]) then
    if to_bridges then
      redis.call('RPUSH', KEYS[2], name .. ' ' .. ARGV[3])
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


def request_steps(names: Iterable[str], *, at: float | None = None, worker: bool = False) -> None:
    """Queue a step for each robot that has none queued yet, on a Celery worker if `worker`; `at` is when
    the cause happened (epoch s)."""
    names = list(names)
    if not names:
        return
    at = time.time() if at is None else at
    keys = [LISTENING, REQUESTED, *(step_marker_key(name) for name in names)]
    for_workers = _request_script()(keys=keys, args=[int(worker), STEP_MARKER_SECONDS, repr(at), *names])
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
