"""Celery tasks: thin wrappers that call services and own only queueing and retry policy."""

import logging
import math
import threading
import time

import requests
from celery import Task, shared_task
from celery.signals import worker_ready
from django.conf import settings
from django.db import connections

from changes.services import changes_trim
from kit.db import drop_broken_connections
from missions import selectors as mission_selectors
from missions.services import mission_notify_finished, missions_assign
from missions.trips import stations_plan_run
from missions.zone_plan import zones_plan_run
from robots.status import robot_check_heartbeats
from stations.selectors import stations_exist
from workers.long_lived import keep_trying, retry_delay, settle_long_lived_process
from workers.step_requests import (
    ASSIGN_TASK,
    STEP_TASK,
    ZONES_TASK,
    assignment_run_finished,
    assignment_run_started,
    queue_assignment,
    queue_steps,
    queue_zones_plan,
    zones_plan_started,
)
from workers.step_runs import NOTIFY_TASK, step_and_publish
from zones.selectors import zone_sets_enabled

logger = logging.getLogger(__name__)

# The reference's retryable notify statuses.
RETRYABLE_HTTP_STATUSES = frozenset({408, 425, 429, 500, 502, 503, 504})


@shared_task(name=STEP_TASK, bind=True, ignore_result=True, max_retries=None)
def step_robots(self: Task, names: list[str], requested_at: float | None = None) -> None:
    """Step each robot in turn. Those whose step failed (PostgreSQL or Redis away) are retried together,
    with backoff, until their steps run: nothing else would step a robot whose state arrived meanwhile."""
    failed = []
    for name in names:
        try:
            step_and_publish(name, requested_at=requested_at)
        except Exception:
            # The traceback once per outage: thousands of robots fail together while PostgreSQL is away.
            logger.warning("step of robot %s failed", name, exc_info=not failed and not self.request.retries)
            failed.append(name)
            drop_broken_connections()  # the next robot's step connects again if this one's connection broke
    if failed:
        delay = retry_delay(self.request.retries + 1)
        logger.warning("steps of %d robots failed; trying them again in %.1f s", len(failed), delay)
        raise self.retry(args=(failed, requested_at), countdown=delay)


# When this process's assignment runs last brought the waiting reasons up to date (monotonic s).
_reasons_refreshed_at = -math.inf


@shared_task(name=ASSIGN_TASK, ignore_result=True)
def assign_missions() -> None:
    """Bind unbound missions to free capable robots, with the waiting reasons when beat asks (a run that
    reads every robot) or this process has not brought them up to date for `ASSIGNMENT_CHECK_SECONDS`; a
    burst still arriving is run again later. Then send robots to charge or park (the same wake-ups concern
    both: a robot freed, back online, changed). The marker goes first: a request made during the run queues
    one more, which sees what this one may have read too early."""
    global _reasons_refreshed_at
    reasons_asked = assignment_run_started()
    since_refreshed = time.monotonic() - _reasons_refreshed_at
    with_reasons = reasons_asked or since_refreshed >= settings.ASSIGNMENT_CHECK_SECONDS
    if with_reasons:
        _reasons_refreshed_at = time.monotonic()
    run = missions_assign(with_reasons=with_reasons)
    assignment_run_finished(idle_robots=run.idle_robots)
    if run.hold is not None:
        queue_assignment(countdown=run.hold)
    stations_plan_run()


@shared_task(name="fleet.assign_waiting", ignore_result=True)
def assign_waiting() -> None:
    """Beat's safety net for assignment: a run while unbound missions wait, whatever wake-up was lost (or
    a robot became free in a way nothing asks a run for: charged, out of teleop, its error cleared); and
    the stations' clock while there are stations (batteries run low and fill up without a wake-up)."""
    if mission_selectors.unbound_missions_wait():
        queue_assignment(with_reasons=True)
    elif stations_exist():
        queue_assignment()


@shared_task(name=ZONES_TASK, ignore_result=True)
def plan_zones() -> None:
    """Who holds which RELEASE zone, how far each order reaches (`missions.zone_plan`). The marker goes
    first: a request made during the run queues one more, which sees what this one may have read too early."""
    zones_plan_started()
    zones_plan_run()


@shared_task(name="fleet.plan_zones_while_enabled", ignore_result=True)
def plan_zones_while_enabled() -> None:
    """Beat's clock for the zone plan while a map has an enabled zone set (robots fall silent, leave zones
    and report positions without a step asking for a run), or an order is still held back by a zone (its
    set disabled: the run steps its robot until the step has released it)."""
    if zone_sets_enabled() or mission_selectors.orders_held_back():
        queue_zones_plan()


class NotifyFailedRetryably(Exception):
    """A notify call that failed in a way the reference tries again: no response, or a retryable status."""


@shared_task(
    name=NOTIFY_TASK,
    bind=True,
    ignore_result=True,
    autoretry_for=(NotifyFailedRetryably,),
    max_retries=settings.NOTIFY_RETRIES,
    retry_backoff=settings.NOTIFY_BACKOFF_SECONDS,  # s before the first retry, doubling per retry
    retry_backoff_max=settings.NOTIFY_BACKOFF_SECONDS * 2**settings.NOTIFY_RETRIES,  # no cap of Celery's
    retry_jitter=False,
)
def run_notify(self: Task, mission: str, node: str) -> None:
    """POST the notify node's json_data to its url; a retryable failure is tried again (by Celery, with
    backoff) while retries are left, and any other outcome finishes the node."""
    params = mission_selectors.notify_params(mission=mission, node=node)
    if params is None:
        return  # the mission ended or moved on meanwhile
    try:
        response = requests.post(params["url"], json=params.get("json_data") or {}, timeout=params["timeout"])
    except requests.RequestException as exc:
        ok, detail, retryable = False, f"Notify request failed: {exc}", True
    else:
        ok = response.status_code == 200
        detail = f"Notify got HTTP {response.status_code} from {params['url']}"
        retryable = response.status_code in RETRYABLE_HTTP_STATUSES
    if not ok and retryable and self.request.retries < self.max_retries:
        raise NotifyFailedRetryably(detail)
    mission_notify_finished(mission=mission, node=node, success=ok, error_msg=None if ok else detail)


@shared_task(name="fleet.check_heartbeats", ignore_result=True)
def check_heartbeats() -> None:
    robot_check_heartbeats()


@shared_task(name="fleet.sweep", ignore_result=True)
def sweep() -> None:
    """Step robots whose missions or messages wait on time: timeouts, deadlines, resends."""
    queue_steps(mission_selectors.robots_due_for_step())


@shared_task(name="fleet.step_stalled", ignore_result=True)
def step_stalled() -> None:
    """Step robots that finished their mission's order while the mission did not move on."""
    queue_steps(mission_selectors.robots_stalled())


@shared_task(name="fleet.trim_changes", ignore_result=True)
def trim_changes() -> None:
    """Keep the change feed within its retention window."""
    changes_trim()


@worker_ready.connect
def _resume_after_restart(**kwargs: object) -> None:
    """A worker killed mid-step loses that step: step every robot with work once at start, as soon as
    PostgreSQL and Redis let it."""
    settle_long_lived_process()
    threading.Thread(target=_step_robots_with_missions, name="resume", daemon=True).start()


def _step_robots_with_missions() -> None:
    try:
        keep_trying(
            "stepping every robot with work",
            lambda: queue_steps(mission_selectors.robots_with_missions()),
        )
    finally:
        connections.close_all()  # this thread's
