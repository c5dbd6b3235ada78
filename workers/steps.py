"""Requesting dispatch steps: at most one queued step per robot, however many wake-ups arrive."""

import time
from collections.abc import Iterable

from workers import livestate

# A queued-step marker expires on its own, so a step lost with a killed worker cannot block later ones.
STEP_MARKER_SECONDS = 10


def step_marker_key(name: str) -> str:
    return f"{livestate.PREFIX}:step-queued:{name}"


def request_steps(names: Iterable[str], *, at: float | None = None) -> None:
    """Queue a step for each robot that has none queued yet; `at` is when the cause happened (epoch s)."""
    names = list(names)
    at = time.time() if at is None else at
    if not names:
        return
    from workers.tasks import step_robot  # tasks import services, which import this module

    pipe = livestate.client().pipeline(transaction=False)
    for name in names:
        pipe.set(step_marker_key(name), 1, nx=True, ex=STEP_MARKER_SECONDS)
    for name, queued in zip(names, pipe.execute(), strict=True):
        if queued:
            step_robot.delay(name, at)


def step_started(name: str) -> None:
    """Called before a step reads anything, so a change arriving during the step queues another one."""
    livestate.client().delete(step_marker_key(name))
