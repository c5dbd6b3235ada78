"""Step requests turned into Celery step tasks on the `steps` queue, at most one queued step per robot.

`queue_steps` queues them now, in the caller's thread (the bridge for a state that changed what the engine
reads, beat for time that passed); `queue_steps_soon` hands them to this process's sender thread, and is
what the workers app installs into the port the services ask through (`kit.wake.request_steps`: the API
for a change of a mission or robot, the heartbeat check). A robot whose step is already
queued gets no second one; its marker is cleared when its step reads the robot's state
(`robots.livestate.state_for_step`), so a change that arrives during the step queues one more. A task
carries several robots when a bridge batch or a sweep asks for several: Celery's cost per task is of the
order of a step's own, so while step tasks wait in the broker the bridge and the sender threads hold their
requests until they fill a task (`HeldSteps`). Steps a service asked for go before those of robots' states
(`StepPriority`).
"""

import atexit
import logging
import math
import os
import threading
import time
from collections.abc import Iterable
from enum import IntEnum
from typing import Any

import kombu
import kombu.exceptions
import kombu.transport.redis
import redis
from celery import current_app as app  # the roof's (fleet.celery), loaded with the settings
from django.conf import settings

from robots import livestate
from workers import tuning

logger = logging.getLogger(__name__)

STEP_TASK = "fleet.step_robots"  # workers.tasks.step_robots, sent by name: the tasks import this module
ASSIGN_TASK = "fleet.assign_missions"  # workers.tasks.assign_missions
# Exists while an assignment run is queued and has not started: at most one queued at a time. It expires,
# so that a run lost with a killed worker blocks none after it.
ASSIGNMENT_MARKER_KEY = f"{livestate.PREFIX}:assignment-queued"
REASONS_ASKED = "reasons"  # the marker's value when the run queued is to bring the waiting reasons up to date
# Exists for ASSIGNMENT_RUN_INTERVAL_SECONDS after a run started: a run asked for meanwhile waits for it.
ASSIGNMENT_RAN_KEY = f"{livestate.PREFIX}:assignment-ran"
# Exists for ASSIGNMENT_FLEET_BUSY_SECONDS after a run left no free robot idle (every robot busy, or bound by
# it): a new unbound mission then asks for its run only once that news is old
# (`request_assignment(defer_while_busy=True)`), so that a busy fleet's runs are not one per new mission.
ASSIGNMENT_FLEET_BUSY_KEY = f"{livestate.PREFIX}:assignment-fleet-busy"
ZONES_TASK = "fleet.plan_zones"  # workers.tasks.plan_zones
# Exists while a zone plan run is queued and has not started; and for ZONES_RUN_INTERVAL_SECONDS after a
# run started (as the assignment's markers).
ZONES_MARKER_KEY = f"{livestate.PREFIX}:zones-queued"
ZONES_RAN_KEY = f"{livestate.PREFIX}:zones-ran"


class StepPriority(IntEnum):
    """A step task's priority. kombu's Redis transport keeps a list per priority step (0, 3, 6, 9) and a
    worker takes from the lowest first. A step a service asked for (an API call, an assignment's binding,
    the heartbeat check) is often a mission's start with a client waiting for it: it goes before the steps
    of robots' states and of beat's sweeps, of which a busy fleet has a backlog."""

    ASKED = 0
    ROUTINE = 6


def step_queue_keys() -> list[str]:
    """The steps queue's lists in a Redis broker, one per priority step, as kombu's transport names them."""
    separator = kombu.transport.redis.Channel.sep
    return [
        settings.STEP_QUEUE if priority == 0 else f"{settings.STEP_QUEUE}{separator}{priority}"
        for priority in kombu.transport.redis.PRIORITY_STEPS
    ]


def queue_steps(
    names: Iterable[str], *, at: float | None = None, priority: StepPriority = StepPriority.ROUTINE
) -> int:
    """Queue a step for each robot that has none queued yet; `at` is when the cause happened (epoch s).
    Returns the step tasks waiting in the broker that these queue behind (`_backlog_commands`).

    One Redis round trip marks them (and reads the backlog), one Celery task per `STEP_TASK_ROBOTS` of them
    carries them."""
    names = list(dict.fromkeys(names))
    if not names:
        return 0
    at = time.time() if at is None else at
    marks: list[livestate.Command] = [
        ("SET", livestate.step_marker_key(name), 1, "NX", "EX", tuning.STEP_MARKER_SECONDS) for name in names
    ]
    replies = _replies(marks + _backlog_commands(priority))
    queued = [name for name, reply in zip(names, replies[: len(names)], strict=True) if reply is not None]
    size = settings.STEP_TASK_ROBOTS
    for start in range(0, len(queued), size):
        try:
            _send_step_task(queued[start : start + size], at, priority)
        except Exception:
            # Unmarked, so that asking again queues them: a marker without its task would block them.
            livestate.round_trip([("DEL", *(livestate.step_marker_key(name) for name in queued[start:]))])
            raise
    return sum(replies[len(names) :])


def _backlog_commands(priority: StepPriority) -> list[livestate.Command]:
    """What reads the step tasks waiting in the broker that a task of `priority` would wait behind (those
    of its priority and before), in the markers' round trip: the broker is the live state's Redis unless an
    operator split them (then the backlog is not read, and counts as none)."""
    if settings.CELERY_BROKER_URL != settings.REDIS_URL:
        return []
    ahead = kombu.transport.redis.PRIORITY_STEPS.index(priority) + 1
    return [("LLEN", key) for key in step_queue_keys()[:ahead]]


class HeldSteps:
    """Step requests of one thread (the bridge's loop, a process's sender thread), at one priority. Sent at
    once while the step workers keep up; while step tasks it would queue behind wait in the broker (every
    worker thread is busy: a worker reserves no more than it runs), held until they fill a task
    (`STEP_TASK_ROBOTS`) or the first has waited `tuning.STEP_HOLD_SECONDS`, so that a busy fleet pays
    Celery's hop, a step's own cost again, once per task of many robots, not per batch of states or per API
    call (issue 42). A held robot's step would have waited behind those tasks anyway. Requests that cannot
    be queued (Redis or the broker away) stay held and go out with the next."""

    def __init__(self, priority: StepPriority = StepPriority.ROUTINE) -> None:
        self.priority = priority
        self._names: dict[str, None] = {}  # insertion-ordered: robots are stepped in request order
        self._at: float | None = None  # when the first held request's cause happened (epoch s)
        self._held_since = 0.0  # monotonic s
        self._backlog = 0  # step tasks ahead of these in the broker at the last send

    def __bool__(self) -> bool:
        return bool(self._names)

    def request(self, names: Iterable[str], *, at: float) -> None:
        """Ask for steps of `names` because of something that happened at `at` (epoch s)."""
        if not self._names:
            self._held_since = time.monotonic()
        self._names.update(dict.fromkeys(names))
        if self._names:
            self._at = at if self._at is None else min(self._at, at)
        self.send_if_due()

    def send_if_due(self) -> None:
        if self._names and self._hold_seconds() == 0.0:
            self._backlog = queue_steps(self._names, at=self._at, priority=self.priority)
            self._names, self._at = {}, None

    def wait_seconds(self, longest: float | None) -> float | None:
        """How long the caller may wait for something else before the held requests are due: `longest`
        (None: for ever) while none are held."""
        if not self._names:
            return longest
        hold = self._hold_seconds()
        return hold if longest is None else min(longest, hold)

    def _hold_seconds(self) -> float:
        if not self._backlog or len(self._names) >= settings.STEP_TASK_ROBOTS:
            return 0.0
        return max(0.0, self._held_since + tuning.STEP_HOLD_SECONDS - time.monotonic())


def queue_assignment(
    *, countdown: float = 0.0, defer_while_busy: bool = False, with_reasons: bool = False
) -> None:
    """Queue an assignment run unless one is queued already (`ASSIGNMENT_MARKER_KEY`), to start in
    `countdown` s, and no sooner than `ASSIGNMENT_RUN_INTERVAL_SECONDS` after the last run started;
    `defer_while_busy`: nor before the news of a busy fleet is old (`ASSIGNMENT_FLEET_BUSY_KEY`);
    `with_reasons`: the run (this one or the one queued already) brings the waiting reasons up to date.
    One round trip to Redis."""
    expiry = tuning.ASSIGNMENT_MARKER_SECONDS + math.ceil(countdown)  # a busy fleet's wait is far shorter
    marker = (ASSIGNMENT_MARKER_KEY, REASONS_ASKED if with_reasons else 1)
    marked, since_last, busy_for, *_ = _replies(
        [
            ("SET", *marker, "NX", "EX", expiry),
            ("PTTL", ASSIGNMENT_RAN_KEY),
            ("PTTL", ASSIGNMENT_FLEET_BUSY_KEY),
            *([("SET", *marker, "XX", "KEEPTTL")] if with_reasons else []),  # the queued run's, if any
        ]
    )
    if marked is None:
        return
    waits = [countdown, since_last / 1000, busy_for / 1000 if defer_while_busy else 0.0]  # PTTL: -2 if none
    _send_run(ASSIGN_TASK, ASSIGNMENT_MARKER_KEY, countdown=max(waits))


def queue_zones_plan() -> None:
    """Queue a zone plan run unless one is queued already (`ZONES_MARKER_KEY`), to start no sooner than
    `ZONES_RUN_INTERVAL_SECONDS` after the last run started. One round trip to Redis."""
    marked, since_last = _replies(
        [("SET", ZONES_MARKER_KEY, 1, "NX", "EX", tuning.ZONES_MARKER_SECONDS), ("PTTL", ZONES_RAN_KEY)]
    )
    if marked is None:
        return
    _send_run(ZONES_TASK, ZONES_MARKER_KEY, countdown=max(since_last / 1000, 0.0))  # PTTL: -2 if none


def _replies(commands: list[livestate.Command]) -> list[Any]:
    """`livestate.round_trip`, raising the first error reply: a request half made must not pass for made."""
    replies = livestate.round_trip(commands)
    for reply in replies:
        if isinstance(reply, Exception):
            raise reply
    return replies


def _send_run(task: str, marker_key: str, *, countdown: float) -> None:
    """Send a run task (assignment, zone plan) whose marker the caller has just set: if the send fails the
    marker goes too, as a marker without its task would block every later run."""
    try:
        app.send_task(
            task, (), queue=settings.STEP_QUEUE, producer=_thread_producer(), countdown=countdown or None
        )
    except Exception:
        livestate.round_trip([("DEL", marker_key)])
        raise


def zones_plan_started() -> None:
    """Let the next request queue a run (the run starting reads the robots afterwards), not to start
    before `ZONES_RUN_INTERVAL_SECONDS` from now."""
    interval_ms = int(tuning.ZONES_RUN_INTERVAL_SECONDS * 1000)
    livestate.round_trip([("DEL", ZONES_MARKER_KEY), ("SET", ZONES_RAN_KEY, 1, "PX", interval_ms)])


def assignment_run_finished(*, idle_robots: int | None) -> None:
    """Remember whether the run left a free robot idle (`ASSIGNMENT_FLEET_BUSY_KEY`); None: not known."""
    if idle_robots == 0:
        milliseconds = int(tuning.ASSIGNMENT_FLEET_BUSY_SECONDS * 1000)
        livestate.round_trip([("SET", ASSIGNMENT_FLEET_BUSY_KEY, 1, "PX", milliseconds)])
    else:
        livestate.round_trip([("DEL", ASSIGNMENT_FLEET_BUSY_KEY)])


def assignment_run_started() -> bool:
    """Let the next request queue a run (the run starting reads the missions afterwards), not to start
    before `ASSIGNMENT_RUN_INTERVAL_SECONDS` from now; whether this run was asked for the reasons."""
    interval_ms = int(tuning.ASSIGNMENT_RUN_INTERVAL_SECONDS * 1000)
    marker, _ = livestate.round_trip(
        [("GETDEL", ASSIGNMENT_MARKER_KEY), ("SET", ASSIGNMENT_RAN_KEY, 1, "PX", interval_ms)]
    )
    return marker == REASONS_ASKED.encode()


def _send_step_task(names: list[str], at: float, priority: StepPriority) -> None:
    """Send one step task with this thread's producer, its arguments' representation (what `celery inspect`
    and Flower show) written by `repr`: Celery's pool checkout per send and its `saferepr` cost a quarter of
    a send's CPU (bench/HISTORY.md), and the bridge sends one per batch of states."""
    args = (names, at)
    app.send_task(
        STEP_TASK,
        args,
        queue=settings.STEP_QUEUE,
        priority=int(priority),
        producer=_thread_producer(),
        argsrepr=repr(args),
        kwargsrepr="{}",
    )


_thread_local = threading.local()


def _thread_producer() -> kombu.Producer:
    """This thread's producer, on a broker connection of its own; a forked child makes its own. Not one of
    Celery's pool: every thread that sends would keep a connection out of it, and the pool is bounded."""
    owned = getattr(_thread_local, "owned", None)
    if owned is None or owned[0] != os.getpid():
        owned = _thread_local.owned = (os.getpid(), app.amqp.Producer(app.connection_for_write()))
    return owned[1]


def queue_steps_soon(names: Iterable[str]) -> None:
    """`queue_steps` at `StepPriority.ASKED` from this process's sender thread, which the caller does not
    wait for.

    For callers whose change is committed already (an API request, beat's heartbeat check): the change
    stands whether or not its step can be queued now, so the caller must not fail for it. Requests made
    while the sender sends go out together with the next send, and while asked-for step tasks wait in the
    broker they are held until they fill a task (`HeldSteps`): under a burst of API requests a task
    carries several robots, and Celery's cost per task is paid once for them.
    """
    _sender.add(names, at=time.time())


def queue_assignment_soon(defer_while_busy: bool = False) -> None:
    """`queue_assignment` from this process's sender thread (as `queue_steps_soon`)."""
    wanted = Assignment.DEFERRED_WHILE_BUSY if defer_while_busy else Assignment.RUN
    _sender.add((), at=time.time(), assignment=wanted)


def queue_zones_plan_soon() -> None:
    """`queue_zones_plan` from this process's sender thread (as `queue_steps_soon`)."""
    _sender.add((), at=time.time(), zones=True)


class Assignment(IntEnum):
    """What a sender is asked of assignment; a stronger request covers a weaker one."""

    NONE = 0
    DEFERRED_WHILE_BUSY = 1  # `queue_assignment(defer_while_busy=True)`
    RUN = 2


class _StepSender:
    """Sends the requested steps from a thread of its own; while Redis or the broker is away it keeps
    them and tries again every `tuning.UNQUEUED_RETRY_SECONDS` until they are queued."""

    def __init__(self) -> None:
        self._names: dict[str, None] = {}  # insertion-ordered: robots are stepped in request order
        self._assignment = Assignment.NONE
        self._zones = False
        self._at: float | None = None  # when the oldest of them was requested
        self._sending = False
        self._holding = False  # the sender thread holds requests back (`HeldSteps`)
        self._changed = threading.Condition()
        self._thread: threading.Thread | None = None

    def add(
        self,
        names: Iterable[str],
        *,
        at: float,
        assignment: Assignment = Assignment.NONE,
        zones: bool = False,
    ) -> None:
        with self._changed:
            self._names.update(dict.fromkeys(names))
            self._assignment = max(self._assignment, assignment)
            self._zones = self._zones or zones
            if not self._names and not self._assignment and not self._zones:
                return
            self._at = at if self._at is None else min(self._at, at)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._send_forever, name="step-sender", daemon=True)
                self._thread.start()
            self._changed.notify_all()

    def wait_until_queued(self, timeout: float) -> bool:
        """Wait until every request made so far is queued (at exit); False if `timeout` s passed first."""
        with self._changed:
            return self._changed.wait_for(
                lambda: (
                    not self._names
                    and not self._assignment
                    and not self._zones
                    and not self._sending
                    and not self._holding
                ),
                timeout,
            )

    def _send_forever(self) -> None:
        held = HeldSteps(StepPriority.ASKED)
        failing = False
        while True:
            with self._changed:
                self._changed.wait_for(
                    lambda: self._names or self._assignment or self._zones, held.wait_seconds(None)
                )
                names, at, assignment = list(self._names), self._at or time.time(), self._assignment
                zones = self._zones
                self._names, self._at, self._assignment, self._sending = {}, None, Assignment.NONE, True
                self._zones = False
            try:
                held.request(names, at=at)  # kept while they are not queued
                if assignment:
                    queue_assignment(defer_while_busy=assignment is Assignment.DEFERRED_WHILE_BUSY)
                if zones:
                    queue_zones_plan()
            except (redis.RedisError, kombu.exceptions.OperationalError, OSError) as error:
                if not failing:
                    logger.warning(
                        "steps not queued (%s); trying again every %s s", error, tuning.UNQUEUED_RETRY_SECONDS
                    )
                failing = True
                self.add((), at=at, assignment=assignment, zones=zones)
                time.sleep(tuning.UNQUEUED_RETRY_SECONDS)
            else:
                if failing:
                    logger.info("steps queued again after the outage")
                failing = False
            finally:
                with self._changed:
                    self._sending, self._holding = False, bool(held)
                    self._changed.notify_all()


_sender = _StepSender()


def wait_until_queued(timeout: float = 2.0) -> bool:
    """Wait until the steps requested so far with `queue_steps_soon` are queued; False if `timeout` s
    passed first (Redis or the broker away). Run at exit, so that a stopping API process loses none."""
    return _sender.wait_until_queued(timeout)


atexit.register(wait_until_queued)
