"""Enumerations of the missions app, spelled as in the reference API."""

from django.db import models

from robots.choices import Lifecycle

__all__ = ["FailureCategory", "Lifecycle", "MissionState", "NodeKind"]


class MissionState(models.TextChoices):
    """State of a mission and of each node of its tree."""

    PENDING = "PENDING"
    RUNNING = "RUNNING"
    COMPLETED = "COMPLETED"
    CANCELED = "CANCELED"
    FAILED = "FAILED"


DONE_STATES = frozenset({MissionState.COMPLETED, MissionState.CANCELED, MissionState.FAILED})


class FailureCategory(models.TextChoices):
    ROBOT_APP = "ROBOT_APP"
    TIMEOUT = "TIMEOUT"
    DEADLINE = "DEADLINE"
    CANCELED = "CANCELED"


class NodeKind(models.TextChoices):
    """The kinds a mission tree node can have; each node has exactly one."""

    SELECTOR = "selector"
    SEQUENCE = "sequence"
    ROUTE = "route"
    MOVE = "move"
    ACTION = "action"
    NOTIFY = "notify"
    CONSTANT = "constant"
