"""Running dispatch steps: one step with what it sends (`run_step`), and the bridge's step threads.

The API and beat request steps through Celery (`workers.steps`); the bridge runs the steps its robots'
states call for on threads of its own (`StepRunner`), which spares every state a Celery round trip. Either
way a step takes the robot's row lock, so steps of one robot never interleave, and it reads the robot's
latest stored state, so a duplicate or late step finds nothing to do.
"""

import logging
import queue
import threading
import time
from collections.abc import Iterable

from django.conf import settings
from django.db import close_old_connections

from missions.services import robot_step
from workers import livestate, metrics
from workers.publish import publish
from workers.steps import request_steps

logger = logging.getLogger(__name__)


def run_step(name: str, *, requested_at: float | None = None) -> None:
    """Step robot `name`, then send what the step decided and count what happened.

    `requested_at` (epoch s) is when the cause happened: the step latency metric counts from there."""
    outcome = robot_step(name=name)
    counters = livestate.client().pipeline(transaction=False)
    if outcome.address is not None:
        publish(
            robot=name,
            address=outcome.address,
            instant_actions_key=outcome.instant_actions_key,
            messages=outcome.messages,
            counters=counters,
        )
    if outcome.notifies:
        from workers.tasks import run_notify  # tasks import this module

        for mission, node in outcome.notifies:
            run_notify.apply_async((mission, node), queue=settings.NOTIFY_QUEUE)
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
    if len(counters):
        counters.execute()


class StepRunner:
    """Runs robots' steps on a few threads of this process, in the order requested.

    At most one step per robot waits in the queue: a request for a robot whose step is already queued adds
    nothing, one for a robot whose step is running queues one more, so a change that arrives during a step
    is always seen. The threads overlap the steps' waits on PostgreSQL, Redis and each other's row locks.
    """

    def __init__(self, threads: int) -> None:
        self.threads = threads
        self._queue: queue.SimpleQueue[tuple[str, float]] = queue.SimpleQueue()
        self._queued: set[str] = set()
        self._lock = threading.Lock()

    def request(self, names: Iterable[str], *, at: float | None = None) -> None:
        """Queue a step for each robot that has none queued; `at` is when the cause happened (epoch s)."""
        at = time.time() if at is None else at
        with self._lock:
            for name in names:
                if name not in self._queued:
                    self._queued.add(name)
                    self._queue.put((name, at))

    def queued(self) -> set[str]:
        """The robots whose step waits in the queue."""
        with self._lock:
            return set(self._queued)

    def start(self) -> None:
        for index in range(self.threads):
            threading.Thread(target=self._run_forever, name=f"step-{index}", daemon=True).start()

    def run_next(self, timeout: float | None = None) -> str | None:
        """Run the next queued step (waiting up to `timeout` s for one); the robot's name, or None."""
        try:
            name, at = self._queue.get(timeout=timeout)
        except queue.Empty:
            return None
        with self._lock:
            self._queued.discard(name)  # before the step reads anything: a later change queues another
        try:
            run_step(name, requested_at=at)
        except Exception:  # one robot's failed step must not stop the others'; a worker tries it again
            logger.exception("step of robot %s failed; handing it to a worker", name)
            request_steps([name], at=at)
        return name

    def _run_forever(self) -> None:
        while True:
            close_old_connections()  # a connection broken by the last step is replaced, not reused
            self.run_next()
