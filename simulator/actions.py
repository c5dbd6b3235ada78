"""The actions a simulated robot can perform, what each one does when it runs, and how it is running.

Node and edge actions become an ``ActionPlan`` (how long, whether it fails, what it changes); instant
actions are carried out by ``simulator.instant``, this module only names and describes them so the
factsheet can list everything. Every action the robot knows of is an ``ActionRun``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from vda5050.maps import MAP_DOWNLOAD_LINK, MAP_HASH, MAP_ID, MAP_VERSION
from vda5050.models import Action, ActionScope, ActionState, ActionStatus, ActionType, ValueDataType
from vda5050.state import FINAL_ACTION_STATUSES
from vda5050.zones import ZONE_SET_ID

LOAD_MAP_SECONDS = 1.0
DOWNLOAD_MAP_SECONDS = 1.0  # a downloadMap is RUNNING this long, then the map is there, DISABLED
PICK_DROP_SECONDS = 1.0


class VendorAction(StrEnum):
    """Action types of NVIDIA's robots (Isaac Mission Dispatch) that the simulator performs."""

    DUMMY_ACTION = "dummy_action"
    PAUSE_ORDER = "pause_order"
    LOAD_MAP = "load_map"


@dataclass(frozen=True)
class ParameterSpec:
    key: str
    value_data_type: ValueDataType
    description: str
    is_optional: bool = False


@dataclass(frozen=True)
class ActionSpec:
    """One entry of the factsheet's ``agvActions``."""

    action_type: str
    description: str
    scopes: tuple[ActionScope, ...]
    parameters: tuple[ParameterSpec, ...] = ()
    result_description: str | None = None


NODE_SCOPES = (ActionScope.NODE, ActionScope.EDGE)
INSTANT_SCOPE = (ActionScope.INSTANT,)
# Charging (VDA 5050's predefined actions), only by robots that can charge (the factsheet lists them then).
CHARGING_ACTIONS = frozenset({ActionType.START_CHARGING, ActionType.STOP_CHARGING})
# What every map action (downloadMap, enableMap, deleteMap) names.
MAP_PARAMETERS = (
    ParameterSpec(MAP_ID, ValueDataType.STRING, "the map"),
    ParameterSpec(MAP_VERSION, ValueDataType.STRING, "its version"),
)

# 3.0's zone set actions, only 3.0 robots know them (the factsheet of a 2.x robot lists none).
ZONE_SET_ACTIONS = frozenset({ActionType.ENABLE_ZONE_SET, ActionType.DELETE_ZONE_SET})
ZONE_SET_PARAMETERS = (ParameterSpec(ZONE_SET_ID, ValueDataType.STRING, "the zone set"),)

ACTION_SPECS: tuple[ActionSpec, ...] = (
    ActionSpec(
        VendorAction.DUMMY_ACTION,
        "Waits `time` seconds, then finishes, or fails if `should_fail` is true.",
        NODE_SCOPES,
        (
            ParameterSpec("should_fail", ValueDataType.BOOL, 'true/false, 1/0 or "true"/"false"/"1"/"0"'),
            ParameterSpec("time", ValueDataType.NUMBER, "seconds to run"),
        ),
    ),
    ActionSpec(VendorAction.PAUSE_ORDER, "Runs until a stopTeleop instant action arrives.", NODE_SCOPES),
    ActionSpec(
        VendorAction.LOAD_MAP,
        "Switches the robot to another map (takes 1 s).",
        NODE_SCOPES,
        (ParameterSpec("map_id", ValueDataType.STRING, "the map to switch to"),),
    ),
    ActionSpec(
        ActionType.PICK,
        "Picks up a load (takes 1 s).",
        NODE_SCOPES,
        (
            ParameterSpec("loadId", ValueDataType.STRING, "id of the picked load", is_optional=True),
            ParameterSpec("loadType", ValueDataType.STRING, "type of the picked load", is_optional=True),
        ),
    ),
    ActionSpec(ActionType.DROP, "Drops every load (takes 1 s).", NODE_SCOPES),
    ActionSpec(
        ActionType.START_CHARGING,
        "Starts charging: the battery rises until it is full, the robot drives off, or stopCharging.",
        (ActionScope.INSTANT, ActionScope.NODE),
    ),
    ActionSpec(ActionType.STOP_CHARGING, "Stops charging.", (ActionScope.INSTANT, ActionScope.NODE)),
    ActionSpec(ActionType.CANCEL_ORDER, "Stops and drops the current order.", INSTANT_SCOPE),
    ActionSpec(ActionType.START_PAUSE, "Stops driving until stopPause.", INSTANT_SCOPE),
    ActionSpec(ActionType.STOP_PAUSE, "Resumes after startPause.", INSTANT_SCOPE),
    ActionSpec(ActionType.STATE_REQUEST, "Publishes a state message.", INSTANT_SCOPE),
    ActionSpec(ActionType.FACTSHEET_REQUEST, "Publishes the factsheet.", INSTANT_SCOPE),
    ActionSpec(ActionType.START_TELEOP, "Hands the robot to teleoperation: no driving.", INSTANT_SCOPE),
    ActionSpec(
        ActionType.STOP_TELEOP, "Ends teleoperation and finishes a running pause_order.", INSTANT_SCOPE
    ),
    ActionSpec(
        ActionType.DOWNLOAD_MAP,
        "Downloads a map version (takes 1 s); it is then reported DISABLED. A version the robot has fails.",
        INSTANT_SCOPE,
        (
            *MAP_PARAMETERS,
            ParameterSpec(MAP_DOWNLOAD_LINK, ValueDataType.STRING, "where to download it (not fetched)"),
            ParameterSpec(MAP_HASH, ValueDataType.STRING, "hash of the download", is_optional=True),
        ),
    ),
    ActionSpec(
        ActionType.ENABLE_MAP,
        "Enables a map version the robot has; the other versions of its mapId are disabled.",
        INSTANT_SCOPE,
        MAP_PARAMETERS,
    ),
    ActionSpec(
        ActionType.DELETE_MAP,
        "Deletes a map version the robot has.",
        INSTANT_SCOPE,
        MAP_PARAMETERS,
    ),
    ActionSpec(
        ActionType.ENABLE_ZONE_SET,
        "Enables a zone set the robot holds (sent on the zoneSet topic); its map's other sets are disabled.",
        INSTANT_SCOPE,
        ZONE_SET_PARAMETERS,
    ),
    ActionSpec(
        ActionType.DELETE_ZONE_SET, "Deletes a zone set the robot holds.", INSTANT_SCOPE, ZONE_SET_PARAMETERS
    ),
    ActionSpec(
        ActionType.INIT_POSITION,
        "Sets the robot's pose.",
        INSTANT_SCOPE,
        (
            ParameterSpec("x", ValueDataType.NUMBER, "m"),
            ParameterSpec("y", ValueDataType.NUMBER, "m"),
            ParameterSpec("theta", ValueDataType.NUMBER, "rad"),
            ParameterSpec("mapId", ValueDataType.STRING, "map of the pose"),
            ParameterSpec("lastNodeId", ValueDataType.STRING, "node the robot stands on", is_optional=True),
        ),
    ),
)


class UnusableAction(ValueError):
    """An action of an unknown type or with missing/unusable parameters; it fails at once."""


@dataclass(frozen=True)
class SetMap:
    map_id: str


@dataclass(frozen=True)
class SetLoad:
    load_id: str | None
    load_type: str | None


@dataclass(frozen=True)
class ClearLoads:
    pass


@dataclass(frozen=True)
class SetCharging:
    charging: bool


Effect = SetMap | SetLoad | ClearLoads | SetCharging


@dataclass(frozen=True)
class ActionPlan:
    """How an order action will run: ``duration`` None means until an outside event (stopTeleop)."""

    duration: float | None
    fails: bool = False
    result: str = "done"
    effects: tuple[Effect, ...] = field(default=())


@dataclass
class ActionRun:
    """An action the robot knows of: one entry of ``actionStates`` plus how it is running."""

    action: Action
    status: ActionStatus = ActionStatus.WAITING
    result: str | None = None
    plan: ActionPlan | None = None
    ends_at: float | None = None  # None while running: until an outside event (stopTeleop)
    instant: bool = False  # reported in 3.0's instantActionStates, not actionStates

    @property
    def done(self) -> bool:
        return self.status in FINAL_ACTION_STATUSES

    def finish(self, result: str) -> None:
        self.status = ActionStatus.FINISHED
        self.result = result

    def fail(self, reason: str) -> None:
        self.status = ActionStatus.FAILED
        self.result = reason

    def to_state(self) -> ActionState:
        return ActionState(
            action_id=self.action.action_id,
            action_type=self.action.action_type,
            action_description=self.action.action_description,
            action_status=self.status,
            result_description=self.result,
        )


def plan_order_action(action: Action, instant: bool, *, can_charge: bool) -> ActionPlan:
    """What a node/edge action will do; raises UnusableAction if the robot cannot do it."""
    parameters = parameters_of(action)
    if action.action_type in CHARGING_ACTIONS and can_charge:
        starts = action.action_type == ActionType.START_CHARGING
        result = "charging" if starts else "charging stopped"
        return ActionPlan(0.0, result=result, effects=(SetCharging(starts),))
    match action.action_type:
        case VendorAction.DUMMY_ACTION:
            should_fail = as_bool(require(parameters, "should_fail"), "should_fail")
            seconds = as_seconds(require(parameters, "time"), "time")
            result = "failed on request (should_fail)" if should_fail else "done"
            return ActionPlan(0.0 if instant else seconds, fails=should_fail, result=result)
        case VendorAction.PAUSE_ORDER:
            return ActionPlan(None, result="resumed by stopTeleop")
        case VendorAction.LOAD_MAP:
            map_id = require(parameters, "map_id")
            if not isinstance(map_id, str) or not map_id:
                raise UnusableAction("map_id must be a non-empty string")
            return ActionPlan(
                0.0 if instant else LOAD_MAP_SECONDS, result=f"map {map_id} loaded", effects=(SetMap(map_id),)
            )
        case ActionType.PICK:
            load = SetLoad(optional_str(parameters, "loadId"), optional_str(parameters, "loadType"))
            return ActionPlan(0.0 if instant else PICK_DROP_SECONDS, result="picked", effects=(load,))
        case ActionType.DROP:
            return ActionPlan(
                0.0 if instant else PICK_DROP_SECONDS, result="dropped", effects=(ClearLoads(),)
            )
    raise UnusableAction(f"unsupported action type {action.action_type!r}")


def parameters_of(action: Action) -> dict[str, Any]:
    return {parameter.key: parameter.value for parameter in action.action_parameters or ()}


def require(parameters: dict[str, Any], key: str) -> Any:
    if key not in parameters:
        raise UnusableAction(f"missing parameter {key!r}")
    return parameters[key]


def optional_str(parameters: dict[str, Any], key: str) -> str | None:
    value = parameters.get(key)
    return None if value is None else str(value)


def as_bool(value: Any, key: str) -> bool:
    """Masters send booleans as JSON booleans, numbers or strings (Isaac sends ``str(True)``)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int | float):
        return value != 0
    if isinstance(value, str) and value.strip().lower() in ("1", "true"):
        return True
    if isinstance(value, str) and value.strip().lower() in ("0", "false"):
        return False
    raise UnusableAction(f"parameter {key!r} is not a boolean: {value!r}")


def as_number(value: Any, key: str) -> float:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    raise UnusableAction(f"parameter {key!r} is not a number: {value!r}")


def as_seconds(value: Any, key: str) -> float:
    seconds = as_number(value, key)
    if not 0 <= seconds < float("inf"):
        raise UnusableAction(f"parameter {key!r} must be a finite number of seconds >= 0")
    return seconds
