"""Which robot goes to charge or park at which station, and when it stops charging (issue 44): records in,
trips, releases and waiting reasons out, no I/O.

The rules, in the order they decide:

- Reservations first: a station holds at most `capacity` robots (reserved, on their way, or there) and a
  robot holds at most one station. A reservation is released when its robot is gone or offline (past its
  heartbeat timeout), holds another station too (the first by station name is kept), holds a parking
  station and is no longer idle or has left it (it got a mission), or holds a charger its charging trip
  failed to reach.
- Back at its charger: a robot charging (no stopCharging of ours pending) at the pose of a charger it may
  use but holding none — its reservation was released while it was offline — takes that charger again
  where it has room, and charges on under the rules below; where the charger went to another robot
  meanwhile, it is sent stopCharging (then, if low, it is sent elsewhere or waits like any low robot). A
  robot charging anywhere else charges by someone else's doing, and is left alone.
- Stop charging: a robot at its charger stops (stopCharging, its charger released) once its battery reaches
  `recommended_maximum`, or once the robot no longer reports `charging` (full, where that is null).
- Charging: a robot is low at or below `recommended_minimum` (where that is null, its critical level), or
  when an operator asked it to charge now. A low robot that is online, idle (no running mission, not in
  teleop), whose factsheet lists `startCharging`, that holds no charger and whose last failed trip's
  backoff has passed gets the nearest free charger it may use (its type; on its map), operators' requests
  first, then the lowest battery when chargers are scarce. A robot parked leaves its parking station for
  the charger.
- Parking (when `park_after_seconds` is set): a robot idle that long, online, not low, holding no station,
  gets the nearest free parking station it may use on its map, the longest idle first.
- Every robot wanting a charge without a charging trip gets one waiting reason, the first that holds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from dispatch.assignment import Pose
from dispatch.vocabulary import StationKind
from vda5050.orders import DEFAULT_ALLOWED_DEVIATION_XY

__all__ = [
    "CHARGING",
    "NOT_IDLE",
    "NO_CHARGER",
    "NO_FREE_CHARGER",
    "NO_POSE",
    "NO_START_CHARGING",
    "OFFLINE",
    "RETRY_LATER",
    "Battery",
    "Pose",
    "Release",
    "Resume",
    "StationPlan",
    "StationRobot",
    "StationSite",
    "Trip",
    "plan_stations",
]

# Why a low robot gets no charging trip: the first that holds, in this order.
CHARGING = "charging"  # it holds a charger: on its way, or charging there
OFFLINE = "offline"
NOT_IDLE = "running a mission or in teleop"
NO_START_CHARGING = "factsheet lists no startCharging"
NO_POSE = "no pose on a map"
NO_CHARGER = "no charger it may use on its map"
NO_FREE_CHARGER = "no free charger"
RETRY_LATER = "its last charging trip failed: retrying later"

# Why a reservation is released.
GONE = "robot gone or offline"
HELD_TWICE = "robot holds another station"
OVER_CAPACITY = "station over capacity"
GOT_MISSION = "robot got a mission"
CHARGED = "charged"
LEFT_FOR_CHARGER = "left for a charger"
TRIP_FAILED = "charging trip failed"

# How near a station's pose a robot stands at it: the deviation its trip's last node allows.
AT_STATION_METRES = DEFAULT_ALLOWED_DEVIATION_XY


@dataclass(frozen=True)
class Battery:
    level: float  # as the robot reports it, in the unit of the thresholds below
    critical_level: float
    recommended_minimum: float | None
    recommended_maximum: float | None
    charging: bool  # VDA 5050 batteryState.charging

    @property
    def low(self) -> bool:
        """At or below its recommended minimum (where that is null, its critical level)."""
        threshold = self.critical_level
        if self.recommended_minimum is not None:
            threshold = max(threshold, self.recommended_minimum)
        return self.level <= threshold

    @property
    def charged(self) -> bool:
        """Done at its charger: at its recommended maximum, or no longer charging (full where that is null;
        else it stopped by itself: restarted, unplugged, driven off), so that its charger is never held
        by a robot that does not charge there."""
        if not self.charging:
            return True
        return self.recommended_maximum is not None and self.level >= self.recommended_maximum


@dataclass(frozen=True)
class StationRobot:
    name: str
    robot_type: str | None
    pose: Pose | None
    online: bool
    idle: bool  # no running mission, not in teleop
    battery: Battery
    can_charge: bool  # its factsheet lists startCharging
    at_station: bool  # its trip to the station it holds has ended (startCharging done, for a charger)
    idle_since: datetime | None  # None: not idle, or since when is not known
    trip_failed: bool = False  # its latest charging trip failed (or was canceled) before it charged
    retry_at: datetime | None = None  # no new charging trip before then (a failed trip's backoff)
    charge_now: bool = False  # an operator asked it to charge now, whatever its battery
    left_parking: bool = False  # a client's mission started since its latest parking trip ended
    stopping: bool = False  # its latest stopCharging is not reported FINISHED (pending, or refused)

    @property
    def wants_charge(self) -> bool:
        return self.charge_now or self.battery.low

    @property
    def charges_on(self) -> bool:
        """Charging, online, and not told to stop: a robot that may hold the charger it stands at."""
        return self.online and self.battery.charging and not self.stopping


@dataclass(frozen=True)
class StationSite:
    name: str
    kind: StationKind
    pose: Pose
    robot_types: frozenset[str]  # empty: any robot
    capacity: int
    reservations: tuple[str, ...]  # robots holding it, in the order they got it
    theta: float = 0.0  # the heading a robot there takes

    def serves(self, robot: StationRobot) -> bool:
        on_map = robot.pose is not None and robot.pose.map_id == self.pose.map_id
        return on_map and (not self.robot_types or robot.robot_type in self.robot_types)

    def charges(self, robot: StationRobot) -> bool:
        """A charger the robot may use, the robot charging on at its pose."""
        return (
            self.kind == StationKind.CHARGER
            and robot.charges_on
            and self.serves(robot)
            and _distance(robot, self) <= AT_STATION_METRES
        )


@dataclass(frozen=True)
class Trip:
    """A robot sent to a station, reserved for it first."""

    robot: str
    station: str
    kind: StationKind
    leaves: str | None = None  # the station it held until now (released), if any


@dataclass(frozen=True)
class Release:
    robot: str
    station: str
    reason: str


@dataclass(frozen=True)
class Resume:
    """A robot charging at a charger it held no more (offline meanwhile) that takes it again."""

    robot: str
    station: str


@dataclass(frozen=True)
class StationPlan:
    charging_trips: tuple[Trip, ...]
    parking_trips: tuple[Trip, ...]
    # Robots to send stopCharging: charged (their charger is among the releases), or back at a charger
    # another robot holds now.
    stop_charging: tuple[str, ...]
    releases: tuple[Release, ...]
    resumed: tuple[Resume, ...]
    waiting: dict[str, str]  # robot wanting a charge -> why it has no charging trip
    reservations: dict[str, tuple[str, ...]]  # every station -> the robots holding it after this plan


def plan_stations(
    robots: Sequence[StationRobot],
    stations: Sequence[StationSite],
    *,
    now: datetime,
    park_after_seconds: float | None,
) -> StationPlan:
    """The trips, releases and waiting reasons for these robots and stations, by the module's rules."""
    by_name = {robot.name: robot for robot in robots}
    stations = sorted(stations, key=lambda station: station.name)
    kinds = {station.name: station.kind for station in stations}
    sites = {station.name: station for station in stations}
    held: dict[str, list[str]] = {station.name: [] for station in stations}
    holding: dict[str, str] = {}  # robot -> the station it holds
    releases: list[Release] = []

    def reserve(robot: StationRobot, station: StationSite) -> None:
        held[station.name].append(robot.name)
        holding[robot.name] = station.name

    for station in stations:
        for name in station.reservations:
            robot = by_name.get(name)
            if robot is None or not robot.online:
                releases.append(Release(name, station.name, GONE))
            elif name in holding:
                releases.append(Release(name, station.name, HELD_TWICE))
            elif station.kind == StationKind.PARKING and (not robot.idle or robot.left_parking):
                releases.append(Release(name, station.name, GOT_MISSION))
            elif station.kind == StationKind.CHARGER and robot.trip_failed and not station.charges(robot):
                releases.append(Release(name, station.name, TRIP_FAILED))
            elif len(held[station.name]) >= station.capacity:
                releases.append(Release(name, station.name, OVER_CAPACITY))
            else:
                reserve(robot, station)

    resumed, stop_charging = [], []
    back = sorted(
        (robot for robot in robots if robot.charges_on and robot.name not in holding),
        key=lambda robot: (robot.battery.level, robot.name),
    )
    for robot in back:
        at = [station for station in stations if station.charges(robot)]
        if not at:
            continue
        free = [station for station in at if len(held[station.name]) < station.capacity]
        if free:
            charger = _nearest(robot, free)
            resumed.append(Resume(robot.name, charger.name))
            reserve(robot, charger)
        else:
            stop_charging.append(robot.name)

    for name, station in sorted(holding.items()):
        robot = by_name[name]
        at_charger = robot.at_station or sites[station].charges(robot)
        if kinds[station] == StationKind.CHARGER and at_charger and robot.battery.charged:
            stop_charging.append(name)
            releases.append(Release(name, station, CHARGED))
            held[station].remove(name)
            del holding[name]

    def release_for_trip(robot: StationRobot) -> str | None:
        left = holding.pop(robot.name, None)
        if left is not None:
            held[left].remove(robot.name)
            releases.append(Release(robot.name, left, LEFT_FOR_CHARGER))
        return left

    charging_trips, waiting = [], {}
    chargers = [station for station in stations if station.kind == StationKind.CHARGER]
    low = sorted(
        (robot for robot in robots if robot.wants_charge),
        key=lambda robot: (not robot.charge_now, robot.battery.level, robot.name),
    )
    for robot in low:
        reason = _charging_blocked(robot, holding, kinds, now=now)
        if reason is None:
            usable = [station for station in chargers if station.serves(robot)]
            free = [station for station in usable if len(held[station.name]) < station.capacity]
            if free:
                charger = _nearest(robot, free)
                charging_trips.append(
                    Trip(robot.name, charger.name, StationKind.CHARGER, release_for_trip(robot))
                )
                reserve(robot, charger)
                continue
            reason = NO_FREE_CHARGER if usable else NO_CHARGER
        waiting[robot.name] = reason

    parking_trips = []
    if park_after_seconds is not None:
        parking = [station for station in stations if station.kind == StationKind.PARKING]
        idle = sorted(
            (robot for robot in robots if _parks(robot, holding, now=now, after=park_after_seconds)),
            key=lambda robot: (robot.idle_since, robot.name),
        )
        for robot in idle:
            free = [
                station
                for station in parking
                if station.serves(robot) and len(held[station.name]) < station.capacity
            ]
            if free:
                place = _nearest(robot, free)
                parking_trips.append(Trip(robot.name, place.name, StationKind.PARKING))
                reserve(robot, place)

    return StationPlan(
        charging_trips=tuple(charging_trips),
        parking_trips=tuple(parking_trips),
        stop_charging=tuple(sorted(stop_charging)),
        releases=tuple(releases),
        resumed=tuple(resumed),
        waiting=waiting,
        reservations={name: tuple(robots_there) for name, robots_there in held.items()},
    )


def _charging_blocked(
    robot: StationRobot, holding: dict[str, str], kinds: dict[str, StationKind], *, now: datetime
) -> str | None:
    """Why a low robot gets no charging trip before a charger is looked for; None: it may get one."""
    if kinds.get(holding.get(robot.name, "")) == StationKind.CHARGER:
        return CHARGING
    if not robot.online:
        return OFFLINE
    if not robot.idle:
        return NOT_IDLE
    if not robot.can_charge:
        return NO_START_CHARGING
    if robot.pose is None:
        return NO_POSE
    if robot.retry_at is not None and now < robot.retry_at:
        return RETRY_LATER
    return None


def _parks(robot: StationRobot, holding: dict[str, str], *, now: datetime, after: float) -> bool:
    """Idle for `after` seconds, online, not wanting a charge, holding no station."""
    return (
        robot.online
        and robot.idle
        and robot.idle_since is not None
        and (now - robot.idle_since).total_seconds() >= after
        and not robot.wants_charge
        and robot.name not in holding
    )


def _nearest(robot: StationRobot, stations: list[StationSite]) -> StationSite:
    """The station nearest the robot in a straight line (all on its map); equal distances by name."""
    return min(stations, key=lambda station: (_distance(robot, station), station.name))


def _distance(robot: StationRobot, station: StationSite) -> float:
    """In a straight line, the robot on the station's map."""
    assert robot.pose is not None
    return math.hypot(station.pose.x - robot.pose.x, station.pose.y - robot.pose.y)
