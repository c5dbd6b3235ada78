"""Reads of robots."""

from collections.abc import Mapping
from typing import Any

from django.db.models import OuterRef, QuerySet

from fleet.api import QueryValidationError, object_get
from robots.filters import RobotFilter
from robots.models import InstantAction, Robot
from vda5050.state import FINAL_ACTION_STATUSES
from vda5050.topics import RobotAddress


def robot_get(*, name: str, to_change: bool = False) -> Robot:
    """The robot called `name`; a missing one is the reference's 400 (PUT/DELETE wording if `to_change`)."""
    return object_get(Robot.objects.all(), alias="robot", name=name, to_change=to_change)


def robot_list(*, filters: Mapping[str, Any] | None = None) -> QuerySet[Robot]:
    """Robots by name, narrowed by the GET /robot query filters (see RobotFilter); any lifecycle."""
    filterset = RobotFilter(data=filters or {}, queryset=Robot.objects.order_by("name"))
    if not filterset.is_valid():
        raise QueryValidationError.from_form_errors(filterset.errors)
    return filterset.qs


def robot_address(robot: Robot) -> RobotAddress:
    """Where the robot's VDA 5050 topics live, and the protocol version it speaks."""
    return RobotAddress(
        interface_name=robot.interface_name,
        manufacturer=robot.manufacturer,
        serial_number=robot.serial_number,
        version=robot.protocol_version,
    )


def robot_unfinished_instant_actions(*, robot: Robot | OuterRef) -> QuerySet[InstantAction]:
    """Instant actions the robot has not yet reported FINISHED or FAILED, oldest first."""
    return (
        InstantAction.objects.filter(robot=robot)
        .exclude(status__in=sorted(FINAL_ACTION_STATUSES))
        .order_by("created_at")
    )
