"""Which free robot takes which unbound mission (issue 41): records in, bindings and waiting reasons out,
no I/O.

The rules, in the order they decide:

- Capability: the robot carries every label of the mission's selector, is of one of its robot types (if it
  names any), its factsheet lists every action type, and every map the mission needs is enabled on it (a
  robot that reports no maps at all is never held for maps).
- Free: online, idle (no running mission, not in teleop), battery above its critical level, and nothing of
  its own queue ahead (its own next mission runs first unless the unbound one has a higher priority, or the
  same priority and is older).
- Priority bands, highest first; a band takes its robots before a lower one sees them.
- Within a band, when free capable robots are scarce, the oldest missions get one (the oldest set that can
  be served at all: a younger mission never keeps a robot an older one of its band could have used).
- Among the ways to serve those missions, the one of least total straight-line distance from each robot's
  pose to its mission's first waypoint, on the same map (a robot without a pose on that map counts after
  every robot with one); equal distances go to the longest idle robot.

The bands are solved with ``scipy.optimize.linear_sum_assignment``, globally rather than first come: which
missions get robots first (a maximum-weight matching with weights that fall with age: a transversal
matroid's greedy basis, so the oldest set wins), then the distances among them. Globally good needs the
whole burst at once: while missions arrive faster than robots could be chosen for them and free robots
outnumber them, binding waits (`burst_hold`), since a burst bound as it arrives drives far further (a
1,000 x 1,000 burst bound in two halves: +12 % over the optimum; as it arrived: +96 %, bench/HISTORY.md).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = [
    "ALL_BUSY",
    "ALL_LOW_BATTERY",
    "NONE_ONLINE",
    "NOT_YET_ASSIGNED",
    "NO_ACTION_TYPES",
    "NO_LABELS",
    "NO_MAP",
    "NO_MAPS_TOGETHER",
    "NO_ROBOTS",
    "NO_ROBOT_TYPE",
    "WAITING_TURN",
    "Assignment",
    "CandidateRobot",
    "Pose",
    "QueueHead",
    "RobotSelector",
    "UnboundMission",
    "assign",
    "burst_hold",
    "choices_of",
]

# Why a mission waits: one reason per unbound mission, the first that holds in this order. The capability
# reasons name the first requirement (labels, robot types, action types, maps) that no robot meeting the
# ones before it meets; the others are about the capable robots' state.
NO_ROBOTS = "No robot exists"
# A new mission without a robot, until the first assignment run has looked at it.
NOT_YET_ASSIGNED = "Waiting for assignment to choose a robot"
NO_LABELS = "No robot carries labels {labels}"
NO_ROBOT_TYPE = "No robot of type {robot_types}"
NO_ACTION_TYPES = "No robot's factsheet lists action types {action_types}"
NO_MAP = "Map {map_id} is not enabled on any capable robot"
NO_MAPS_TOGETHER = "No capable robot has maps {map_ids} enabled together"
NONE_ONLINE = "No capable robot is online"
ALL_LOW_BATTERY = "Every capable robot's battery is low (below its critical level, or due to charge)"
ALL_BUSY = "Every capable robot is busy"
WAITING_TURN = "Waiting for a higher-priority or older mission"

# Ranking the free robots of a mission: a robot without a pose on the mission's map counts after every
# one with a pose (its cost is more than all distances of the band together); distances closer than
# IDLE_TIE metres are equal and then the longest idle robot is the cheaper by up to IDLE_TIE.
IDLE_TIE = 1e-6

# A capability check's first failing requirement (the stage), or _CAPABLE.
_LABELS, _ROBOT_TYPE, _ACTION_TYPES, _MAPS, _CAPABLE = range(5)


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    map_id: str


@dataclass(frozen=True)
class RobotSelector:
    """Who can do a mission; an empty field asks nothing."""

    labels: frozenset[str] = frozenset()  # the robot carries every one
    robot_types: frozenset[str] = frozenset()  # the robot is of any one
    action_types: frozenset[str] = frozenset()  # the robot's factsheet lists every one


@dataclass(frozen=True)
class UnboundMission:
    name: str
    priority: int  # higher first
    created: datetime  # older first among equal priorities
    selector: RobotSelector
    start: Pose | None  # its first waypoint; None: no robot is nearer than another
    maps: frozenset[str]  # the map ids its routes need, enabled on the robot where it reports maps


@dataclass(frozen=True)
class QueueHead:
    """A robot's own next mission (named for it): it runs before unbound missions it outranks."""

    priority: int
    created: datetime


@dataclass(frozen=True)
class CandidateRobot:
    name: str
    labels: frozenset[str]
    robot_type: str | None
    action_types: frozenset[str] | None  # its factsheet's; None: no factsheet (lists nothing)
    pose: Pose | None
    online: bool
    idle: bool  # no running mission, not in teleop
    battery_ok: bool  # above its critical level
    enabled_maps: frozenset[str] | None  # None: it reports no maps (never held for maps)
    idle_since: datetime | None  # None: counts as the most recently idle
    queue_head: QueueHead | None = None


@dataclass(frozen=True)
class Assignment:
    bindings: dict[str, str]  # mission name -> robot name
    waiting: dict[str, str]  # mission name -> why it is not bound (every unbound mission not in bindings)


def assign(missions: Sequence[UnboundMission], robots: Sequence[CandidateRobot]) -> Assignment:
    """Bind unbound missions to free capable robots by the module's rules; `robots` are all robots (their
    state explains the waiting reasons), bound or not."""
    missions = sorted(missions, key=_mission_order)
    robots = sorted(robots, key=lambda robot: robot.name)  # ties go the same way whatever the input order
    fleet = _Fleet(robots)
    capability = _Capability(missions, robots)
    ages = _age_ranks(missions, robots)
    unavailable = ~fleet.free
    bindings: dict[str, str] = {}
    start = 0
    while start < len(missions):
        end = start
        while end < len(missions) and missions[end].priority == missions[start].priority:
            end += 1
        rows = np.arange(start, end)
        for row, column in _solve_band(missions, rows, fleet, capability, ages, unavailable):
            bindings[missions[row].name] = robots[column].name
            unavailable[column] = True
        start = end
    waiting = {
        mission.name: capability.reason(row, mission, fleet)
        for row, mission in enumerate(missions)
        if mission.name not in bindings
    }
    return Assignment(bindings=bindings, waiting=waiting)


def choices_of(robot: CandidateRobot, missions: Sequence[UnboundMission]) -> list[str]:
    """The unbound missions a free robot may take by the module's rules, best first (the highest priority,
    then the oldest): `assign` would give it the first when it is the only free robot, and it takes the
    next when another robot took that one meanwhile. None if the robot is not free."""
    if not (robot.online and robot.idle and robot.battery_ok):
        return []
    offer = (robot.labels, robot.robot_type, robot.action_types, robot.enabled_maps)
    return [
        mission.name
        for mission in sorted(missions, key=_mission_order)
        if _ahead_of(mission, robot.queue_head) and _stage(mission.selector, mission.maps, *offer) == _CAPABLE
    ]


def _mission_order(mission: UnboundMission) -> tuple[int, datetime, str]:
    """Highest priority first, oldest first among equals (names break ties)."""
    return -mission.priority, mission.created, mission.name


def _ahead_of(mission: UnboundMission, head: QueueHead | None) -> bool:
    """The unbound mission goes before the robot's own next mission."""
    if head is None or mission.priority != head.priority:
        return head is None or mission.priority > head.priority
    return mission.created < head.created


def burst_hold(
    created: Sequence[datetime], free_robots: int, *, now: datetime, quiet: timedelta, longest: timedelta
) -> timedelta | None:
    """How much longer to wait before binding the unbound missions created at `created` (None: bind now).

    A burst is held while it arrives: the newest mission is younger than `quiet`, there are fewer missions
    than free robots (with as many missions as robots every robot is used whatever arrives next) and the
    oldest has waited less than `longest` (a steady stream that never pauses is bound that often)."""
    if not created or len(created) >= free_robots:
        return None
    waited = now - min(created)
    hold = min(quiet - (now - max(created)), longest - waited)
    return hold if hold > timedelta(0) else None


class _Fleet:
    """The robots' state as arrays, in the order given."""

    def __init__(self, robots: Sequence[CandidateRobot]) -> None:
        self.robots = robots
        self.online = np.array([robot.online for robot in robots], dtype=bool)
        self.battery_ok = np.array([robot.battery_ok for robot in robots], dtype=bool)
        self.idle = np.array([robot.idle for robot in robots], dtype=bool)
        self.free = self.online & self.idle & self.battery_ok
        self.x = np.array([robot.pose.x if robot.pose else 0.0 for robot in robots], dtype=float)
        self.y = np.array([robot.pose.y if robot.pose else 0.0 for robot in robots], dtype=float)
        self.map_id = [robot.pose.map_id if robot.pose else None for robot in robots]
        # 0 for the longest idle, then up to 1 for the most recently idle (names break ties).
        order = sorted(
            range(len(robots)),
            key=lambda i: (
                robots[i].idle_since is None,
                robots[i].idle_since or datetime.min,
                robots[i].name,
            ),
        )
        self.idle_rank = np.empty(len(robots), dtype=float)
        self.idle_rank[order] = np.arange(len(robots)) / max(1, len(robots) - 1)


def _age_ranks(missions: Sequence[UnboundMission], robots: Sequence[CandidateRobot]) -> _Ages:
    """The creation times of the missions and of the robots' queue heads as dense ranks, comparable in
    numpy."""
    heads = [robot.queue_head for robot in robots]
    times = sorted({mission.created for mission in missions} | {head.created for head in heads if head})
    rank = {created: index for index, created in enumerate(times)}
    return _Ages(
        mission=np.array([rank[mission.created] for mission in missions], dtype=np.int64),
        has_head=np.array([head is not None for head in heads], dtype=bool),
        head_priority=np.array([head.priority if head else 0 for head in heads], dtype=np.int64),
        head_created=np.array([rank[head.created] if head else 0 for head in heads], dtype=np.int64),
    )


@dataclass(frozen=True)
class _Ages:
    mission: np.ndarray  # per mission (sorted as in assign)
    has_head: np.ndarray  # per robot
    head_priority: np.ndarray
    head_created: np.ndarray

    def head_behind(self, rows: np.ndarray, priority: int) -> np.ndarray:
        """(rows x robots): the robot's own next mission lets the unbound one of the row go first."""
        outranked = (self.head_priority < priority) | (
            (self.head_priority == priority)[None, :]
            & (self.mission[rows][:, None] < self.head_created[None, :])
        )
        return ~self.has_head[None, :] | outranked


class _Capability:
    """What each mission's selector and maps ask of each robot, checked once per distinct pair of
    requirements (a mission's signature) and robot abilities (a robot's): real fleets have few of each."""

    def __init__(self, missions: Sequence[UnboundMission], robots: Sequence[CandidateRobot]) -> None:
        asks = [(mission.selector, mission.maps) for mission in missions]
        offers = [
            (robot.labels, robot.robot_type, robot.action_types, robot.enabled_maps) for robot in robots
        ]
        mission_kinds, self.mission_kind = _kinds(asks)
        robot_kinds, self.robot_kind = _kinds(offers)
        # stage[i, j]: how far robots of kind j get with the requirements of mission kind i.
        self.stage = np.array(
            [[_stage(*ask, *offer) for offer in robot_kinds] for ask in mission_kinds], dtype=np.int8
        ).reshape(len(mission_kinds), len(robot_kinds))
        self._reasons: dict[int, str] = {}

    def capable(self, rows: np.ndarray) -> np.ndarray:
        """(rows x robots) booleans."""
        return (self.stage == _CAPABLE)[self.mission_kind[rows]][:, self.robot_kind]

    def reason(self, row: int, mission: UnboundMission, fleet: _Fleet) -> str:
        """Why the mission of the row waits: the same for every mission of its kind."""
        kind = int(self.mission_kind[row])
        if kind not in self._reasons:
            self._reasons[kind] = self._reason(kind, mission, fleet)
        return self._reasons[kind]

    def _reason(self, kind: int, mission: UnboundMission, fleet: _Fleet) -> str:
        if not len(fleet.robots):
            return NO_ROBOTS
        stages = self.stage[kind][self.robot_kind]
        furthest = int(stages.max())
        selector = mission.selector
        if furthest == _LABELS:
            return NO_LABELS.format(labels=", ".join(sorted(selector.labels)))
        if furthest == _ROBOT_TYPE:
            return NO_ROBOT_TYPE.format(robot_types=" or ".join(sorted(selector.robot_types)))
        if furthest == _ACTION_TYPES:
            return NO_ACTION_TYPES.format(action_types=", ".join(sorted(selector.action_types)))
        if furthest == _MAPS:
            held = [fleet.robots[j].enabled_maps or frozenset() for j in np.flatnonzero(stages == _MAPS)]
            enabled = frozenset().union(*held)
            missing = sorted(mission.maps - enabled)
            if missing:
                return NO_MAP.format(map_id=missing[0])
            return NO_MAPS_TOGETHER.format(map_ids=", ".join(sorted(mission.maps)))
        online = (stages == _CAPABLE) & fleet.online
        if not online.any():
            return NONE_ONLINE
        charged = online & fleet.battery_ok
        if not charged.any():
            return ALL_LOW_BATTERY
        if not (charged & fleet.idle).any():
            return ALL_BUSY
        return WAITING_TURN


def _kinds(items: list[Hashable]) -> tuple[list[Hashable], np.ndarray]:
    """The distinct items, and each item's index among them."""
    index: dict[Hashable, int] = {}
    kind = np.array([index.setdefault(item, len(index)) for item in items], dtype=np.int64)
    return list(index), kind


def _stage(
    selector: RobotSelector,
    maps: frozenset[str],
    labels: frozenset[str],
    robot_type: str | None,
    action_types: frozenset[str] | None,
    enabled_maps: frozenset[str] | None,
) -> int:
    """The first requirement a robot with these abilities does not meet, or _CAPABLE."""
    if not selector.labels <= labels:
        return _LABELS
    if selector.robot_types and robot_type not in selector.robot_types:
        return _ROBOT_TYPE
    if not selector.action_types <= (action_types or frozenset()):
        return _ACTION_TYPES
    if enabled_maps is not None and not maps <= enabled_maps:
        return _MAPS
    return _CAPABLE


def _solve_band(
    missions: Sequence[UnboundMission],
    rows: np.ndarray,
    fleet: _Fleet,
    capability: _Capability,
    ages: _Ages,
    unavailable: np.ndarray,
) -> list[tuple[int, int]]:
    """The (mission row, robot column) pairs bound in one priority band; `rows` are oldest first."""
    columns = np.flatnonzero(~unavailable)
    priority = missions[rows[0]].priority
    feasible = capability.capable(rows)[:, columns] & ages.head_behind(rows, priority)[:, columns]
    useful_rows = feasible.any(axis=1)
    useful_columns = feasible.any(axis=0)
    rows, columns = rows[useful_rows], columns[useful_columns]
    feasible = feasible[np.ix_(useful_rows, useful_columns)]
    if not len(rows):
        return []
    served = _oldest_served(feasible)
    rows, feasible = rows[served], feasible[served]
    cost = np.where(feasible, _cost(missions, rows, fleet, columns), np.inf)
    chosen_rows, chosen_columns = linear_sum_assignment(cost)
    return [(int(rows[i]), int(columns[j])) for i, j in zip(chosen_rows, chosen_columns, strict=True)]


def _oldest_served(feasible: np.ndarray) -> np.ndarray:
    """Which rows (oldest first) get a robot: the oldest set that can be served together (a transversal
    matroid's greedy basis, so no younger row is served in place of an older one it could have given way
    to), as the least total weight, weights falling with age, of the rows left without a robot they can
    use. Columns of "none" make every row assigned: the square form scipy solves fast (the same weights as
    gains on feasible pairs took it 40 times as long on 1,000 missions for 950 robots)."""
    count, robots = feasible.shape
    if feasible.all():
        return np.arange(min(count, robots))
    weight = np.arange(count, 0, -1, dtype=float)[:, None]
    none = np.broadcast_to(weight, (count, max(0, count - robots)))
    chosen_rows, chosen_columns = linear_sum_assignment(np.hstack([np.where(feasible, 0.0, weight), none]))
    real = chosen_columns < robots
    chosen_rows, chosen_columns = chosen_rows[real], chosen_columns[real]
    return np.sort(chosen_rows[feasible[chosen_rows, chosen_columns]])


def _cost(
    missions: Sequence[UnboundMission], rows: np.ndarray, fleet: _Fleet, columns: np.ndarray
) -> np.ndarray:
    """(rows x columns): the distance from each robot to each mission's first waypoint; more than all of
    the band's distances together without a pose on that map; plus the idle tie-break."""
    starts = [missions[row].start for row in rows]
    x = np.array([start.x if start else 0.0 for start in starts])
    y = np.array([start.y if start else 0.0 for start in starts])
    has_start = np.array([start is not None for start in starts], dtype=bool)
    map_ids = sorted({start.map_id for start in starts if start})
    code = {map_id: index for index, map_id in enumerate(map_ids)}
    mission_map = np.array([code[start.map_id] if start else -1 for start in starts], dtype=np.int64)
    robot_map = np.array([code.get(fleet.map_id[j], -2) for j in columns], dtype=np.int64)
    distance = np.hypot(x[:, None] - fleet.x[columns][None, :], y[:, None] - fleet.y[columns][None, :])
    on_map = mission_map[:, None] == robot_map[None, :]
    far = distance[on_map].max(initial=0.0) * len(rows) + 1.0
    cost = np.where(on_map, distance, far)
    cost[~has_start] = 0.0
    return cost + IDLE_TIE * fleet.idle_rank[columns][None, :]
