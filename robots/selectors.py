"""Reads of robots."""

from collections.abc import Mapping
from typing import Any

from django.db.models import OuterRef, QuerySet

from kit.api.errors import QueryValidationError
from kit.api.rows import object_get
from robots.choices import MapAction
from robots.filters import RobotFilter
from robots.models import InstantAction, Robot
from vda5050.state import FINAL_ACTION_STATUSES


def robot_get(*, name: str, to_change: bool = False) -> Robot:
    """The robot called `name`; a missing one is the reference's 400 (PUT/DELETE wording if `to_change`)."""
    return object_get(Robot.objects.all(), alias="robot", name=name, to_change=to_change)


def robot_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[Robot]:
    """Robots by name, narrowed by the GET /robot query filters (see RobotFilter); any lifecycle."""
    filterset = RobotFilter(data=filters or {}, queryset=Robot.objects.order_by("name"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def robot_unfinished_instant_actions(*, robot: Robot | str | OuterRef) -> QuerySet[InstantAction]:
    """Instant actions the robot has not yet reported FINISHED or FAILED, oldest first."""
    return (
        InstantAction.objects.filter(robot=robot)
        .exclude(status__in=sorted(FINAL_ACTION_STATUSES))
        .order_by("created_at")
    )


def robot_map_actions(*, robot: Robot) -> QuerySet[InstantAction]:
    """The map actions asked of the robot, newest first, finished or not."""
    return InstantAction.objects.filter(robot=robot, action_type__in=MapAction.values).order_by("-created_at")
