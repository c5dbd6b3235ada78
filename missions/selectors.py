"""Reads of missions."""

from collections.abc import Mapping
from datetime import datetime, timedelta
from typing import Any

from django.conf import settings
from django.db.models import DateTimeField, ExpressionWrapper, F, Q, QuerySet, Value
from django.db.models.fields.json import KT
from django.utils import timezone

from dispatch.held import order_finished, order_lacked
from dispatch.vocabulary import DEFAULT_NOTIFY_TIMEOUT, MissionState
from kit.api.errors import QueryValidationError
from kit.api.rows import object_get
from missions.filters import MissionFilter
from missions.models import Mission
from missions.tuning import STALLED_MISSION_SECONDS, UNNOTICED_MISSION_SECONDS
from robots import livestate
from robots.models import InstantAction, Robot


def mission_get(*, name: str, to_change: bool = False) -> Mission:
    """The mission called `name`; a missing one is the reference's 400 (worded for DELETE if `to_change`)."""
    return object_get(Mission.objects.all(), alias="mission", name=name, to_change=to_change)


def mission_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[Mission]:
    """Missions in queue order, narrowed by the GET /mission query filters (MissionFilter); any lifecycle."""
    filterset = MissionFilter(data=filters or {}, queryset=Mission.objects.order_by("queue_position"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def notify_params(*, mission: str, node: str) -> dict[str, Any] | None:
    """The notify node's params if that node is running right now, else None."""
    row = (
        Mission.objects.filter(name=mission, state=MissionState.RUNNING)
        .values("mission_tree", "node_status")
        .first()
    )
    if row is None or row["node_status"].get(node, {}).get("state") != MissionState.RUNNING:
        return None
    for entry in row["mission_tree"]:
        if entry.get("name") == node and "notify" in entry:
            return {"timeout": DEFAULT_NOTIFY_TIMEOUT, **entry["notify"]}
    return None


def robots_due_for_step(*, now: datetime | None = None) -> list[str]:
    """Robots with something that waits on time: a timeout, a deadline, an unacknowledged message."""
    now = now or timezone.now()
    order_resend = now - timedelta(seconds=settings.DISPATCH_ORDER_RESEND_SECONDS)
    action_resend = now - timedelta(seconds=settings.DISPATCH_INSTANT_ACTION_RESEND_SECONDS)
    timeout_at = ExpressionWrapper(
        F("start_timestamp") + Value(timedelta(seconds=1)) * F("timeout"), output_field=DateTimeField()
    )
    running = Mission.objects.filter(state=MissionState.RUNNING)
    ending = running.annotate(timeout_at=timeout_at).filter(
        Q(timeout_at__lte=now) | Q(deadline__lte=now) | Q(needs_canceled=True)
    )
    unaccepted = running.filter(order_accepted=False, order_sent_at__lte=order_resend)
    pending = Mission.objects.filter(state=MissionState.PENDING, deadline__lte=now)
    # Queued missions no step has looked at, on robots that run nothing: a creation whose wake-up was lost
    # (Redis away, or the API killed between its commit and the wake-up).
    unnoticed = Mission.objects.filter(
        state=MissionState.PENDING,
        waiting_reason__isnull=True,
        created_at__lte=now - timedelta(seconds=UNNOTICED_MISSION_SECONDS),
        robot__in=Robot.objects.values("name"),
    ).exclude(robot__in=Mission.objects.filter(state=MissionState.RUNNING).values("robot"))
    actions = InstantAction.objects.filter(status__isnull=True).filter(
        Q(sent_at__isnull=True) | Q(sent_at__lte=action_resend)
    )
    names = set(ending.values_list("robot", flat=True))
    names.update(_orders_not_taken(unaccepted))
    names.update(pending.values_list("robot", flat=True))
    names.update(unnoticed.values_list("robot", flat=True))
    names.update(actions.values_list("robot_id", flat=True))
    return sorted(names)


def robots_stalled(*, now: datetime | None = None) -> list[str]:
    """Robots idle at the end of the order their running mission sent, or no longer holding it
    (`order_lacked`: a restarted robot), the mission not moved on since; and robots whose order may have
    stalled (`_orders_maybe_stalled`).

    The last line of defence: the state that ended or lost the order asked for a step, and a step that
    failed is retried; but a process killed with that retry pending, a lost request, or a state too early to
    say (`dispatch.held.arrived_after_order`) leaves nothing else to step the robot, which sends no news
    while it idles.
    """
    now = now or timezone.now()
    rows = list(
        Mission.objects.filter(
            state=MissionState.RUNNING,
            order__isnull=False,
            updated_at__lte=now - timedelta(seconds=STALLED_MISSION_SECONDS),
        ).values_list("robot", "order_sent_at", KT("order__orderId"), KT("order__orderUpdateId"))
    )
    held = livestate.orders_held([robot for robot, *_ in rows])
    ended = {
        robot
        for robot, sent_at, order_id, update_id in rows
        if update_id is not None
        and sent_at is not None
        and (
            order_finished(held[robot], order_id=order_id, update_id=int(update_id))
            or order_lacked(held[robot], order_id=order_id, update_id=int(update_id), sent_at=sent_at)
        )
    }
    return sorted(ended | set(_orders_maybe_stalled(now)))


def _orders_maybe_stalled(now: datetime) -> list[str]:
    """Robots whose mission's order has shown no progress for FLEET_ORDER_STALL_SECONDS (its stall clock,
    `dispatch.faults.watch_progress`): a step judges whether the order stalled, as a robot standing still
    sends no state that would wake one."""
    if not settings.DISPATCH_ORDER_STALL_SECONDS:
        return []
    stalled_since = now - timedelta(seconds=settings.DISPATCH_ORDER_STALL_SECONDS)
    return list(
        Mission.objects.filter(state=MissionState.RUNNING, progress_seen_at__lte=stalled_since)
        .values_list("robot", flat=True)
        .distinct()
    )


def _orders_not_taken(missions: QuerySet[Mission]) -> list[str]:
    """The robots of `missions` that lack their mission's order (`order_lacked`)."""
    rows = list(
        missions.values_list("robot", "order_sent_at", KT("order__orderId"), KT("order__orderUpdateId"))
    )
    held = livestate.orders_held([robot for robot, *_ in rows])
    return [
        robot
        for robot, sent_at, order_id, update_id in rows
        if order_lacked(
            held[robot],
            order_id=order_id,
            update_id=-1 if update_id is None else int(update_id),
            sent_at=sent_at,
        )
    ]


def robots_with_missions() -> list[str]:
    """Robots with a running or queued mission."""
    return list(
        Mission.objects.filter(state__in=[MissionState.RUNNING, MissionState.PENDING])
        .values_list("robot", flat=True)
        .distinct()
    )
