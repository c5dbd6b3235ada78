"""The assignment of unbound missions to free capable robots (issue 41): one table of cases per rule, every
waiting reason, and properties checked on generated fleets against the rules written out plainly here and
against brute force on tiny bands."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dispatch.assignment import (
    ALL_BUSY,
    ALL_LOW_BATTERY,
    NO_ACTION_TYPES,
    NO_LABELS,
    NO_MAP,
    NO_MAPS_TOGETHER,
    NO_ROBOT_TYPE,
    NO_ROBOTS,
    NONE_ONLINE,
    WAITING_TURN,
    Assignment,
    CandidateRobot,
    Pose,
    QueueHead,
    RobotSelector,
    UnboundMission,
    assign,
    burst_hold,
    choices_of,
)

T0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)
MAP = "map"


def mission(
    name: str,
    at: tuple[float, float] | None = (0.0, 0.0),
    *,
    priority: int = 0,
    age: int = 0,  # seconds before T0: older missions have larger ages
    labels: tuple[str, ...] = (),
    robot_types: tuple[str, ...] = (),
    action_types: tuple[str, ...] = (),
    map_id: str = MAP,
    maps: tuple[str, ...] | None = None,  # default: the first waypoint's map
) -> UnboundMission:
    return UnboundMission(
        name=name,
        priority=priority,
        created=T0 - timedelta(seconds=age),
        selector=RobotSelector(frozenset(labels), frozenset(robot_types), frozenset(action_types)),
        start=Pose(*at, map_id) if at else None,
        maps=frozenset((map_id,) if maps is None else maps),
    )


def robot(
    name: str,
    at: tuple[float, float] | None = (0.0, 0.0),
    *,
    labels: tuple[str, ...] = (),
    robot_type: str | None = None,
    action_types: tuple[str, ...] | None = None,
    map_id: str = MAP,
    enabled_maps: tuple[str, ...] | None = None,
    online: bool = True,
    idle: bool = True,
    battery_ok: bool = True,
    idle_for: int | None = 0,  # seconds idle before T0; None: unknown
    queue_head: tuple[int, int] | None = None,  # its own next mission's (priority, age)
) -> CandidateRobot:
    return CandidateRobot(
        name=name,
        labels=frozenset(labels),
        robot_type=robot_type,
        action_types=None if action_types is None else frozenset(action_types),
        pose=Pose(*at, map_id) if at else None,
        online=online,
        idle=idle,
        battery_ok=battery_ok,
        enabled_maps=None if enabled_maps is None else frozenset(enabled_maps),
        idle_since=None if idle_for is None else T0 - timedelta(seconds=idle_for),
        queue_head=None
        if queue_head is None
        else QueueHead(queue_head[0], T0 - timedelta(seconds=queue_head[1])),
    )


@dataclass(frozen=True)
class Case:
    missions: list[UnboundMission]
    robots: list[CandidateRobot]
    bindings: dict[str, str]
    waiting: dict[str, str]


CASES = {
    # Capability, each kind: a nearer robot that lacks it loses.
    "labels beat distance": Case(
        [mission("m", labels=("lift",))],
        [robot("near"), robot("far", (50, 0), labels=("lift", "arm"))],
        {"m": "far"},
        {},
    ),
    "robot type, any of those named": Case(
        [mission("m", robot_types=("carter", "nova"))],
        [robot("near", robot_type="other"), robot("far", (50, 0), robot_type="nova")],
        {"m": "far"},
        {},
    ),
    "action types all in the factsheet; no factsheet lists none": Case(
        [mission("m", action_types=("pick", "drop"))],
        [
            robot("near", action_types=("pick",)),
            robot("unknown", (1, 0), action_types=None),
            robot("far", (50, 0), action_types=("pick", "drop", "charge")),
        ],
        {"m": "far"},
        {},
    ),
    "no action types asked: a robot without a factsheet is capable": Case(
        [mission("m")], [robot("unknown", action_types=None)], {"m": "unknown"}, {}
    ),
    "maps: every map needed enabled where the robot reports maps": Case(
        [mission("m", maps=(MAP, "lift"))],
        [robot("near", enabled_maps=(MAP,)), robot("far", (50, 0), enabled_maps=("lift", MAP))],
        {"m": "far"},
        {},
    ),
    "maps: a robot reporting no maps is never held for maps": Case(
        [mission("m", maps=("elsewhere",))],
        [robot("reports", enabled_maps=(MAP,)), robot("silent", (50, 0), enabled_maps=None)],
        {"m": "silent"},
        {},
    ),
    # Free: online, idle, battery above critical.
    "only a free robot takes a mission": Case(
        [mission("m")],
        [
            robot("offline", online=False),
            robot("busy", idle=False),
            robot("low", battery_ok=False),
            robot("free", (90, 90)),
        ],
        {"m": "free"},
        {},
    ),
    # Priority, then age.
    "a higher priority first, however young": Case(
        [mission("old", age=100), mission("urgent", priority=5)],
        [robot("r")],
        {"urgent": "r"},
        {"old": WAITING_TURN},
    ),
    "the oldest first within a priority": Case(
        [mission("young", age=1), mission("old", age=2), mission("new")],
        [robot("r")],
        {"old": "r"},
        {"young": WAITING_TURN, "new": WAITING_TURN},
    ),
    "a higher band takes the robot a lower one was nearer to": Case(
        [mission("low", (10, 0)), mission("high", (9, 0), priority=1)],
        [robot("r1", (10, 0)), robot("r2", (0, 0))],
        {"high": "r1", "low": "r2"},
        {},
    ),
    "scarce robots go to the oldest missions that can be served": Case(
        [mission("young", age=1), mission("old", age=2, labels=("lift",)), mission("oldest", age=3)],
        [robot("lifter", labels=("lift",)), robot("plain", (5, 0))],
        {"old": "lifter", "oldest": "plain"},
        {"young": WAITING_TURN},
    ),
    # Nearest, and globally: the band's total distance, not first come.
    "the nearest free robot": Case(
        [mission("m", (3, 4))], [robot("far", (30, 40)), robot("near", (0, 0))], {"m": "near"}, {}
    ),
    "the least total distance, not the oldest mission's nearest robot": Case(
        [mission("old", (4, 0), age=2), mission("young", (-1, 0), age=1)],
        [robot("r0", (0, 0)), robot("r10", (10, 0))],
        {"old": "r10", "young": "r0"},
        {},
    ),
    "a robot without a pose on the map after one with a pose, however far": Case(
        [mission("m")],
        [
            robot("nowhere", None, idle_for=100),
            robot("upstairs", (0, 0), map_id="floor2", idle_for=100),
            robot("far", (1000, 1000)),
        ],
        {"m": "far"},
        {},
    ),
    "equal distances: the longest idle": Case(
        [mission("m")],
        [
            robot("recent", (3, 0), idle_for=5),
            robot("long", (-3, 0), idle_for=50),
            robot("unknown", (0, 3), idle_for=None),
        ],
        {"m": "long"},
        {},
    ),
    "no pose anywhere: the longest idle": Case(
        [mission("m")],
        [robot("recent", None, idle_for=5), robot("long", None, idle_for=50)],
        {"m": "long"},
        {},
    ),
    "a mission without a first waypoint: the longest idle": Case(
        [mission("m", None, maps=())],
        [robot("near", idle_for=1), robot("long", (99, 0), idle_for=9)],
        {"m": "long"},
        {},
    ),
    # A robot's own queue: its next mission runs first unless the unbound one outranks it.
    "its own higher-priority mission is ahead": Case(
        [mission("m", priority=1, age=9)], [robot("r", queue_head=(2, 0))], {}, {"m": WAITING_TURN}
    ),
    "its own older mission of equal priority is ahead": Case(
        [mission("m", priority=1, age=1)], [robot("r", queue_head=(1, 2))], {}, {"m": WAITING_TURN}
    ),
    "an older unbound mission of equal priority goes first": Case(
        [mission("m", priority=1, age=3)], [robot("r", queue_head=(1, 2))], {"m": "r"}, {}
    ),
    "a higher-priority unbound mission goes first": Case(
        [mission("m", priority=2)], [robot("r", queue_head=(1, 100))], {"m": "r"}, {}
    ),
    "its own queue holds it for one mission, not another": Case(
        [mission("high", priority=3), mission("low", (0, 0), priority=0)],
        [robot("queued", queue_head=(1, 0)), robot("other", (100, 0), online=False)],
        {"high": "queued"},
        {"low": WAITING_TURN},
    ),
    # Every waiting reason.
    "no robot at all": Case([mission("m")], [], {}, {"m": NO_ROBOTS}),
    "no robot carries the labels": Case(
        [mission("m", labels=("lift", "arm"))],
        [robot("r", labels=("lift",))],
        {},
        {"m": NO_LABELS.format(labels="arm, lift")},
    ),
    "no robot of the type": Case(
        [mission("m", labels=("lift",), robot_types=("nova", "carter"))],
        [robot("r", labels=("lift",), robot_type="other"), robot("s", robot_type="nova")],
        {},
        {"m": NO_ROBOT_TYPE.format(robot_types="carter or nova")},
    ),
    "no factsheet lists the action types": Case(
        [mission("m", action_types=("pick",))],
        [robot("r", action_types=("drop",)), robot("s", action_types=None)],
        {},
        {"m": NO_ACTION_TYPES.format(action_types="pick")},
    ),
    "the map is not enabled on any capable robot": Case(
        [mission("m", robot_types=("carter",), maps=(MAP, "lift"))],
        [
            robot("r", robot_type="carter", enabled_maps=(MAP,)),
            robot("other", robot_type="x", enabled_maps=("lift",)),
        ],
        {},
        {"m": NO_MAP.format(map_id="lift")},
    ),
    "the maps are not enabled together on any capable robot": Case(
        [mission("m", maps=(MAP, "lift"))],
        [robot("r", enabled_maps=(MAP,)), robot("s", enabled_maps=("lift",))],
        {},
        {"m": NO_MAPS_TOGETHER.format(map_ids="lift, map")},
    ),
    "no capable robot online": Case(
        [mission("m", labels=("lift",))],
        [robot("r", labels=("lift",), online=False), robot("incapable")],
        {},
        {"m": NONE_ONLINE},
    ),
    "every capable robot's battery below critical": Case(
        [mission("m")],
        [
            robot("low", battery_ok=False),
            robot("low_busy", idle=False, battery_ok=False),
            robot("off", online=False),
        ],
        {},
        {"m": ALL_LOW_BATTERY},
    ),
    "every capable robot busy": Case(
        [mission("m")], [robot("busy", idle=False), robot("low", battery_ok=False)], {}, {"m": ALL_BUSY}
    ),
    "capable free robots taken by others": Case(
        [mission("first", age=2), mission("second", age=1)],
        [robot("r")],
        {"first": "r"},
        {"second": WAITING_TURN},
    ),
}


@pytest.mark.parametrize("case", CASES.values(), ids=CASES.keys())
def test_assignment_rule(case: Case) -> None:
    assert assign(case.missions, case.robots) == Assignment(bindings=case.bindings, waiting=case.waiting)


def test_the_order_of_the_inputs_changes_nothing() -> None:
    missions = [mission(f"m{i}", (i % 3, i // 3), age=i % 4, priority=i % 2) for i in range(9)]
    robots = [robot(f"r{i}", (i % 2, i % 5), idle_for=i % 3) for i in range(6)]

    assert assign(missions, robots) == assign(missions[::-1], robots[::-1])


# --- properties -------------------------------------------------------------------------------------------
# The rules written out plainly, one pair at a time.


def capable(m: UnboundMission, r: CandidateRobot) -> bool:
    return (
        m.selector.labels <= r.labels
        and (not m.selector.robot_types or r.robot_type in m.selector.robot_types)
        and m.selector.action_types <= (r.action_types or frozenset())
        and (r.enabled_maps is None or m.maps <= r.enabled_maps)
    )


def free_for(m: UnboundMission, r: CandidateRobot) -> bool:
    head = r.queue_head
    outranks = head is None or (m.priority, head.created) > (head.priority, m.created)
    return r.online and r.idle and r.battery_ok and outranks


def feasible(m: UnboundMission, r: CandidateRobot) -> bool:
    return capable(m, r) and free_for(m, r)


def distance(m: UnboundMission, r: CandidateRobot) -> float | None:
    """None: the robot has no pose on the mission's map."""
    if m.start is None:
        return 0.0
    if r.pose is None or r.pose.map_id != m.start.map_id:
        return None
    return math.hypot(m.start.x - r.pose.x, m.start.y - r.pose.y)


LABELS = ("a", "b")
MAPS = ("m1", "m2")


def _subset(options: tuple[str, ...]) -> st.SearchStrategy[frozenset[str]]:
    return st.frozensets(st.sampled_from(options), max_size=len(options))


_coordinate = st.integers(0, 6).map(float)
_pose = st.none() | st.builds(Pose, _coordinate, _coordinate, st.sampled_from(MAPS))
_age = st.integers(0, 5).map(lambda seconds: T0 - timedelta(seconds=seconds))
_mostly = st.sampled_from((True, True, True, False))  # robots mostly free, so that missions compete


Fleet = tuple[list[UnboundMission], list[CandidateRobot]]


@st.composite
def fleets(draw: st.DrawFn, bands: int = 3) -> Fleet:
    count = draw(st.integers(0, 5))
    missions = [
        UnboundMission(
            name=f"m{i}",
            priority=draw(st.integers(0, bands - 1)),
            created=draw(_age),
            selector=RobotSelector(
                labels=draw(_subset(LABELS)),
                robot_types=draw(_subset(("t1", "t2"))),
                action_types=draw(_subset(("pick",))),
            ),
            start=draw(_pose),
            maps=draw(_subset(MAPS)),
        )
        for i in range(count)
    ]
    robots = [
        CandidateRobot(
            name=f"r{j}",
            labels=draw(_subset(LABELS)),
            robot_type=draw(st.sampled_from((None, "t1", "t2"))),
            action_types=draw(st.none() | _subset(("pick", "drop"))),
            pose=draw(_pose),
            online=draw(_mostly),
            idle=draw(_mostly),
            battery_ok=draw(_mostly),
            enabled_maps=draw(st.none() | _subset(MAPS)),
            idle_since=draw(st.none() | _age),
            queue_head=draw(st.none() | st.builds(QueueHead, st.integers(0, bands - 1), _age)),
        )
        for j in range(draw(st.integers(0, 5)))
    ]
    return missions, robots


PROPERTIES = settings(max_examples=150, derandomize=True, deadline=None, database=None)


@PROPERTIES
@given(fleets())
def test_every_mission_bound_once_or_waits_and_every_robot_takes_one_at_most(fleet: Fleet) -> None:
    missions, robots = fleet
    result = assign(missions, robots)

    assert set(result.bindings) | set(result.waiting) == {m.name for m in missions}
    assert not set(result.bindings) & set(result.waiting)
    assert len(set(result.bindings.values())) == len(result.bindings)


@PROPERTIES
@given(fleets())
def test_every_binding_is_feasible(fleet: Fleet) -> None:
    missions, robots = fleet
    bindings = assign(missions, robots).bindings
    by_name = {r.name: r for r in robots}

    for m in missions:
        if m.name in bindings:
            assert feasible(m, by_name[bindings[m.name]])


@PROPERTIES
@given(fleets())
def test_no_mission_waits_for_a_robot_a_lower_or_younger_one_took(fleet: Fleet) -> None:
    missions, robots = fleet
    result = assign(missions, robots)
    by_name = {r.name: r for r in robots}

    for waiting, bound in itertools.product(missions, missions):
        if waiting.name in result.waiting and bound.name in result.bindings:
            ahead = (waiting.priority, bound.created, bound.name) > (
                bound.priority,
                waiting.created,
                waiting.name,
            )
            if ahead:
                assert not feasible(waiting, by_name[result.bindings[bound.name]])


@PROPERTIES
@given(fleets())
def test_a_mission_waits_for_capability_only_without_a_capable_robot_and_its_turn_only_beside_a_free_one(
    fleet,
):
    missions, robots = fleet
    result = assign(missions, robots)

    for m in missions:
        if m.name in result.waiting:
            able = [r for r in robots if capable(m, r)]
            reason = result.waiting[m.name]
            assert (reason in {NONE_ONLINE, ALL_LOW_BATTERY, ALL_BUSY, WAITING_TURN}) == bool(able)
            assert (reason == WAITING_TURN) == any(r.online and r.idle and r.battery_ok for r in able)


@PROPERTIES
@given(fleets(bands=1))
def test_a_band_serves_the_oldest_missions_it_can_then_the_least_distance_as_brute_force_does(
    fleet: Fleet,
) -> None:
    missions, robots = fleet
    result = assign(missions, robots)
    by_name = {r.name: r for r in robots}

    best = _brute_force(missions, robots)
    assert set(result.bindings) == best.served
    pairs = [(m, by_name[result.bindings[m.name]]) for m in missions if m.name in result.bindings]
    assert sum(distance(m, r) is None for m, r in pairs) == best.without_pose
    assert sum(distance(m, r) or 0.0 for m, r in pairs) == pytest.approx(best.distance, abs=1e-4)


@dataclass(frozen=True)
class _Best:
    served: set[str]
    without_pose: int
    distance: float


def _brute_force(missions: list[UnboundMission], robots: list[CandidateRobot]) -> _Best:
    """Every way to give each mission a robot or none: the oldest served first (each mission outweighs all
    younger ones together), then the fewest robots without a pose on the map, then the least distance."""
    oldest_first = sorted(missions, key=lambda m: (m.created, m.name))
    choices = [None, *robots]
    best: tuple[float, int, float] | None = None
    best_served: set[str] = set()
    for picks in itertools.product(choices, repeat=len(oldest_first)):
        taken = [r.name for r in picks if r is not None]
        if len(taken) != len(set(taken)):
            continue
        pairs = [(m, r) for m, r in zip(oldest_first, picks, strict=True) if r is not None]
        if not all(feasible(m, r) for m, r in pairs):
            continue
        weight = sum(2 ** (len(missions) - oldest_first.index(m)) for m, _ in pairs)
        distances = [distance(m, r) for m, r in pairs]
        key = (-weight, sum(d is None for d in distances), sum(d or 0.0 for d in distances))
        if best is None or key < best:
            best, best_served = key, {m.name for m, _ in pairs}
    assert best is not None
    return _Best(served=best_served, without_pose=best[1], distance=best[2])


# --- choices_of: what a robot fallen free takes from the pool in its own step ----------------------------


@PROPERTIES
@given(fleets())
def test_a_robots_choices_are_the_missions_feasible_for_it_best_first(fleet: Fleet) -> None:
    missions, robots = fleet
    for robot in robots:
        choices = choices_of(robot, missions)

        assert set(choices) == {m.name for m in missions if feasible(m, robot)}
        ranks = {m.name: (-m.priority, m.created, m.name) for m in missions}
        assert choices == sorted(choices, key=ranks.__getitem__)


@PROPERTIES
@given(fleets())
def test_a_robots_first_choice_is_what_assignment_gives_it_alone(fleet: Fleet) -> None:
    missions, robots = fleet
    for robot in robots:
        alone = assign(missions, [robot]).bindings
        assert choices_of(robot, missions)[:1] == list(alone)


# --- burst_hold: a burst is bound together once it stops arriving ------------------------------------------

QUIET, LONGEST = timedelta(seconds=0.25), timedelta(seconds=10)


def hold(ages: list[float], free_robots: int) -> float | None:
    """burst_hold for missions created `ages` seconds before now, in seconds."""
    now = datetime(2026, 11, 28, tzinfo=UTC)
    created = [now - timedelta(seconds=age) for age in ages]
    held = burst_hold(created, free_robots, now=now, quiet=QUIET, longest=LONGEST)
    return None if held is None else held.total_seconds()


@pytest.mark.parametrize(
    ("ages", "free_robots", "expected"),
    [
        ([], 5, None),  # nothing to hold
        ([0.1, 0.05], 5, 0.2),  # still arriving: until the newest is QUIET old
        ([1.0, 0.5], 5, None),  # paused
        ([0.1, 0.05], 2, None),  # as many missions as free robots: every robot is used anyway
        ([0.1, 0.05, 0.0], 2, None),  # more missions than robots
        ([9.9, 0.0], 5, pytest.approx(0.1)),  # a stream: held no longer than LONGEST after its oldest
        ([10.0, 0.0], 5, None),
        ([0.0], 0, None),  # no free robot: nothing to choose
    ],
)
def test_a_burst_is_held_while_it_arrives_and_robots_outnumber_it(
    ages: list[float], free_robots: int, expected: float | None
) -> None:
    result = hold(ages, free_robots)
    assert result == (pytest.approx(expected) if isinstance(expected, float) else expected)


@settings(max_examples=300, deadline=None)
@given(
    ages=st.lists(st.floats(min_value=0.0, max_value=30.0), min_size=1, max_size=20),
    free_robots=st.integers(min_value=0, max_value=30),
)
def test_a_hold_never_outlasts_the_quiet_or_the_longest_hold(ages: list[float], free_robots: int) -> None:
    result = hold(ages, free_robots)
    if result is None:
        return
    assert len(ages) < free_robots
    assert 0 < result <= QUIET.total_seconds() - min(ages) + 1e-6  # timedelta: whole microseconds
    assert result <= LONGEST.total_seconds() - max(ages) + 1e-6
