"""The fleet's vocabulary, defined once: mission and node states, node kinds (and a notify node's default
timeout), failure categories, robot states and lifecycles, spelled as in the reference API.

Pure Python (no Django, paho or Redis imports), so the pure modules (``dispatch.engine``,
``dispatch.step``) use these enums directly, and the Django choices (``missions.choices``,
``robots.choices``) are built from them. Members are ``str``: they compare equal to, hash as and
serialize to the plain strings stored in the database and in JSON.

Two words the whole house uses in one sense each:
- *spec*: what the API sets on an object (a robot's labels and battery levels, a mission's tree, a
  station's pose);
- *status*: what the dispatch engine and the robot report about an object: a robot's or a mission's
  `status` in the API, a tree's node states (`node_status`), an instant action's status as the robot
  reports it (VDA 5050 `actionStatus`), the robots' reported columns the bridge writes
  (`workers/bridge/status_writer.py`, `robots/status.py`). A state is one value of a status: the
  mission's `state`, the robot's `state`.
"""

from enum import StrEnum

__all__ = [
    "DEFAULT_NOTIFY_TIMEOUT",
    "DONE_STATES",
    "AgvClass",
    "FailureCategory",
    "Lifecycle",
    "MissionPurpose",
    "MissionState",
    "NodeKind",
    "RobotState",
    "StationKind",
]


class MissionState(StrEnum):
    """State of a mission and of each node of its tree."""

    PENDING = "PENDING"
    RUNNING = "RUNNING"
    COMPLETED = "COMPLETED"
    CANCELED = "CANCELED"
    FAILED = "FAILED"


# A mission (or node) in one of these has ended and does not change any more.
DONE_STATES = frozenset({MissionState.COMPLETED, MissionState.CANCELED, MissionState.FAILED})


class FailureCategory(StrEnum):
    """Why a mission did not complete."""

    ROBOT_APP = "ROBOT_APP"
    TIMEOUT = "TIMEOUT"
    DEADLINE = "DEADLINE"
    CANCELED = "CANCELED"


class NodeKind(StrEnum):
    """The kinds a mission tree node can have; each node has exactly one."""

    SELECTOR = "selector"
    SEQUENCE = "sequence"
    ROUTE = "route"
    MOVE = "move"
    ACTION = "action"
    NOTIFY = "notify"
    CONSTANT = "constant"


# Seconds a notify node's call waits for its response when the node does not say: the reference's default.
DEFAULT_NOTIFY_TIMEOUT = 30


class RobotState(StrEnum):
    """What a robot is doing, as the API reports it."""

    IDLE = "IDLE"
    ON_TASK = "ON_TASK"
    CHARGING = "CHARGING"
    MAP_DEPLOYMENT = "MAP_DEPLOYMENT"
    TELEOP = "TELEOP"


class Lifecycle(StrEnum):
    """Lifecycle of a robot or a mission: a deletion is asked for first and done once it is safe."""

    ALIVE = "ALIVE"
    PENDING_DELETE = "PENDING_DELETE"
    DELETED = "DELETED"


class AgvClass(StrEnum):
    """A robot's type: VDA 5050 factsheet `typeSpecification.agvClass` (a robot's `robot_type`, the types a
    station serves)."""

    FORKLIFT = "FORKLIFT"
    CONVEYOR = "CONVEYOR"
    TUGGER = "TUGGER"
    CARRIER = "CARRIER"
    MANIPULATOR = "MANIPULATOR"
    HUMANOID = "HUMANOID"


class MissionPurpose(StrEnum):
    """What a mission the dispatch core made itself is for (a client's missions have none): a trip to a
    charger to charge, or to a parking station to wait."""

    CHARGE = "CHARGE"
    PARK = "PARK"


class StationKind(StrEnum):
    """What a station is for: robots charge at a CHARGER and wait at a PARKING station."""

    CHARGER = "CHARGER"
    PARKING = "PARKING"
