"""Running dispatch steps: one step with what it sends (`run_step`), and the bridge's step threads.

The bridge runs the steps its robots' states call for on threads of its own (`StepRunner`), in a child
process (`StepProcess`), which spares every state a Celery round trip; those threads also take the steps
the API and beat request (`workers.steps`), which go to Celery workers while no bridge listens. Either
way a step takes the robot's row lock, so steps of one robot never interleave, and it reads the robot's
latest stored state, so a duplicate or late step finds nothing to do.
"""

import gc
import heapq
import logging
import math
import multiprocessing
import queue
import sys
import threading
import time
import zlib
from collections.abc import Callable, Iterable
from multiprocessing.connection import Connection

import redis
from django.conf import settings
from django.db import DatabaseError, connections

from fleet.db import drop_broken_connections
from missions.selectors import robots_with_missions
from missions.services import robot_step
from workers import livestate, metrics
from workers.publish import publish
from workers.steps import take_requested

logger = logging.getLogger(__name__)

# A thread whose reply came in takes the interpreter lock back only when the thread holding it lets go:
# at Python's default 5 ms a reply waited up to that long behind one thread's Python code, after every
# round trip of a step (bench/README.md has what 0.5 ms did to step latency).
SWITCH_INTERVAL_SECONDS = 0.0005
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
    """Set up a long-lived bridge process once its startup is done.

    What is loaded by then (Django, the apps, the robot directory) lives as long as the process: frozen, it
    is out of the garbage collector's sight, whose full collections walked it and stopped the process for
    50-170 ms every few seconds. The short switch interval is for the threads that wait on round trips.
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
    if outcome.notifies:
        from workers.tasks import run_notify  # tasks import this module

        for mission, node in outcome.notifies:
            run_notify.apply_async((mission, node), queue=settings.NOTIFY_QUEUE)


class StepRunner:
    """Runs robots' steps on a few threads of this process, in the order requested.

    At most one step per robot waits in the queue: a request for a robot whose step is already queued adds
    nothing, one for a robot whose step is running queues one more, so a change that arrives during a step
    is always seen. The threads overlap the steps' waits on PostgreSQL, Redis and each other's row locks.
    A step that fails is requested again with backoff until it runs: nothing else would step a robot
    whose last state arrived while PostgreSQL was away.
    """

    def __init__(self, threads: int) -> None:
        self.threads = threads
        self._queue: queue.SimpleQueue[tuple[str, float]] = queue.SimpleQueue()
        self._queued: set[str] = set()
        self._lock = threading.Lock()
        self._failures: dict[str, int] = {}  # robot -> its steps that failed in a row
        self._retries: list[tuple[float, str, float]] = []  # heap of (due, monotonic s; robot; at)

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

    def retrying(self) -> dict[str, int]:
        """Robots whose last step failed, and how many of their steps failed in a row."""
        with self._lock:
            return dict(self._failures)

    def start(self) -> None:
        for index in range(self.threads):
            threading.Thread(target=self._run_forever, name=f"step-{index}", daemon=True).start()

    def run_next(self, timeout: float | None = None) -> str | None:
        """Run the next queued step (waiting up to `timeout` s for one, or for a failed one's retry to be
        due); the robot's name, or None."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            retry_in = self._queue_due_retries()
            wait = retry_in if deadline is None else min(retry_in or math.inf, deadline - time.monotonic())
            try:
                name, at = self._queue.get(timeout=None if wait is None else max(0.0, wait))
                break
            except queue.Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    return None
        with self._lock:
            self._queued.discard(name)  # before the step reads anything: a later change queues another
        try:
            run_step(name, requested_at=at)
        except Exception:  # one robot's failed step must not stop the others'
            self._retry_later(name, at)
        else:
            if name in self._failures:
                with self._lock:
                    self._failures.pop(name, None)
        return name

    def _retry_later(self, name: str, at: float) -> None:
        with self._lock:
            failures = self._failures[name] = self._failures.get(name, 0) + 1
            delay = retry_delay(failures)
            heapq.heappush(self._retries, (time.monotonic() + delay, name, at))
        # The traceback once per robot and outage: thousands of robots fail together while PostgreSQL is away.
        logger.warning(
            "step of robot %s failed (%d in a row); trying again in %.1f s",
            name,
            failures,
            delay,
            exc_info=failures == 1,
        )

    def _queue_due_retries(self) -> float | None:
        """Queue the failed steps whose retry is due; seconds until the next one is, or None."""
        now = time.monotonic()
        due = []
        with self._lock:
            while self._retries and self._retries[0][0] <= now:
                due.append(heapq.heappop(self._retries))
            retry_in = self._retries[0][0] - now if self._retries else None
        for _, name, at in due:
            self.request([name], at=at)
        return retry_in

    def _run_forever(self) -> None:
        while True:
            drop_broken_connections()  # a connection broken by the last step is replaced, not reused
            self.run_next()

    def listen(self) -> None:
        """Also run the steps requested through Redis (`workers.steps`): the API's and beat's."""
        threading.Thread(target=self._take_requested_forever, name="step-requests", daemon=True).start()

    def _take_requested_forever(self) -> None:
        while True:
            try:
                for name, at in take_requested():
                    self.request([name], at=at)
            except redis.RedisError:  # Redis away for a moment: Celery workers take the requests meanwhile
                logger.exception("taking requested steps failed; going on in 1 s")
                time.sleep(1)


class StepProcess:
    """A `StepRunner` in a child process, fed the bridge's step requests over a pipe.

    In the bridge's own process the step threads waited for the interpreter lock after every round trip,
    behind the thread that parses ~1,000 messages/s: a step of 2 ms of CPU took ~15 ms and the steps queued
    (step latency p50 110 ms at 1,000 robots). A child of its own runs them without that wait. The child is
    forked before the bridge starts any thread or connection (a restart forks the running bridge: only the
    forking thread lives on in the child, and redis-py and logging reset their locks and pools after a
    fork), ends when the bridge's end of the pipe closes (the bridge exited or was killed), and is started
    again if it dies.
    """

    def __init__(self, threads: int) -> None:
        self.threads = threads
        self._process: multiprocessing.process.BaseProcess | None = None
        self._sender: Connection | None = None

    def start(self) -> None:
        connections.close_all()  # a forked child must not share the parent's database connections
        receiver, sender = multiprocessing.get_context("fork").Pipe(duplex=False)
        _senders.add(sender)
        self._process = multiprocessing.get_context("fork").Process(
            target=_serve_steps, args=(receiver, self.threads), name="bridge-steps", daemon=True
        )
        self._process.start()
        receiver.close()
        self._sender = sender

    def request(self, names: Iterable[str], *, at: float | None = None) -> None:
        """Queue a step for each robot in the child; `at` is when the cause happened (epoch s)."""
        names = list(names)
        if not names:
            return
        message = (names, time.time() if at is None else at)
        if self._sender is not None:
            try:
                self._sender.send(message)
                return
            except OSError:  # the child died: its end of the pipe is closed
                pass
        # Steps the dead child had queued are lost: step every robot with work once, as at a start.
        logger.error("bridge step process is not running; starting it")
        self.close()
        self.start()
        assert self._sender is not None
        self._sender.send(message)
        try:
            self._sender.send((robots_with_missions(), message[1]))
        except DatabaseError:  # PostgreSQL away: beat's sweep finds the robots whose step was lost
            logger.exception("could not step every robot with work")

    def close(self) -> None:
        """Close the pipe, which ends the child (a step it is running is rolled back), and wait for it."""
        if self._sender is not None:
            _senders.discard(self._sender)
            self._sender.close()
            self._sender = None
        if self._process is not None:
            self._process.join(timeout=10)
            self._process = None

    @property
    def pid(self) -> int | None:
        """The child's process id while it is started."""
        return None if self._process is None else self._process.pid


# The sending ends of this process's step-process pipes. A child inherits every one open when it is forked
# and closes them all: only the bridge may hold them, or a pipe would outlive it and its child never end.
_senders: set[Connection] = set()


def _serve_steps(receiver: Connection, threads: int) -> None:
    """The child's main thread: requests off the pipe into the step threads, until the bridge is gone."""
    for sender in _senders:
        sender.close()  # only the bridge holds the sending ends, so its exit ends `recv` below
    settle_long_lived_process()
    runner = StepRunner(threads)
    runner.start()
    runner.listen()
    while True:
        try:
            names, at = receiver.recv()
        except EOFError:
            return
        runner.request(names, at=at)


class StepProcesses:
    """Several `StepProcess` children, so that the steps of a busy fleet are not limited to the one core
    that a process's interpreter lock allows. A robot's steps always go to the same child, whose queue
    holds at most one step per robot; a restarted child steps every robot with work once, the others'
    too (harmless: a robot's steps serialize on its row lock).
    """

    def __init__(self, processes: int, threads: int) -> None:
        self.children = [StepProcess(threads) for _ in range(processes)]

    def start(self) -> None:
        for child in self.children:
            child.start()

    def request(self, names: Iterable[str], *, at: float | None = None) -> None:
        """Queue a step for each robot in its child; `at` is when the cause happened (epoch s)."""
        by_child: dict[StepProcess, list[str]] = {}
        for name in names:
            by_child.setdefault(self.child_of(name), []).append(name)
        for child, group in by_child.items():
            child.request(group, at=at)

    def child_of(self, name: str) -> StepProcess:
        return self.children[zlib.crc32(name.encode()) % len(self.children)]

    def close(self) -> None:
        for child in self.children:
            child.close()
