"""The zone access core (dispatch.zones): table-driven cases of its rules, the two robots whose routes
cross two zones in opposite orders, and property tests that simulate robots driving random routes through
random zone layouts with the core deciding every tick: never more robots in a zone than it admits, and
every robot arrives (no deadlock, no robot waiting for ever)."""

import random
from dataclasses import dataclass, field

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dispatch.zones import (
    RobotRoute,
    RoutePoint,
    Zone,
    ZoneKey,
    ZoneRequest,
    decide,
    zone_requests,
    zones_at,
    zones_on,
)
from vda5050.models import Request
from vda5050.zones import GrantType

STALLED = 60  # ticks without a move: the robots are stuck
PROPERTIES = settings(max_examples=400, derandomize=True, deadline=None, database=None)
MAP = "map"


def box(
    zone_id: str, x0: float, y0: float, x1: float, y1: float, capacity: int = 1, map_id: str = MAP
) -> Zone:
    return Zone(map_id, zone_id, ((x0, y0), (x1, y0), (x1, y1), (x0, y1)), capacity)


def at(x: float, y: float, map_id: str = MAP) -> RoutePoint:
    return RoutePoint(x, y, map_id)


def line(*xs: float, y: float = 0.0) -> tuple[RoutePoint, ...]:
    return tuple(at(x, y) for x in xs)


# An aisle from x=2 to x=4 across y=0; a robot driving along y=0 from x=0 to x=6 crosses it.
AISLE = box("aisle", 2.0, -1.0, 4.0, 1.0)
AISLE_KEY = (MAP, "aisle")
THROUGH = line(1.0, 3.0, 5.0, 6.0)  # nodes ahead of a robot at x=0: node 1 (x=3) is inside the aisle


ORIGIN = at(0.0, 0.0)


def robot(name: str, route=THROUGH, start=ORIGIN, **fields) -> RobotRoute:
    return RobotRoute(robot=name, position=start, route=route, **fields)


# --- the rules, case by case ---------------------------------------------------------------------------


def test_a_robot_gets_a_free_zone_and_its_base_reaches_through_it():
    decision = decide(zones=[AISLE], robots=[robot("a")], holders={})

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert decision.horizons == {"a": 4}  # through the aisle (x=3) and on: nothing else is in the way
    assert decision.waiting == {}


def test_a_second_robot_waits_at_the_last_node_before_the_zone():
    decision = decide(zones=[AISLE], robots=[robot("a"), robot("b", since=1.0)], holders={})

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert decision.horizons["b"] == 1  # only x=1, before the aisle
    assert decision.waiting == {"b": frozenset({AISLE_KEY})}


def test_a_holder_keeps_its_grant_and_a_higher_priority_waits_for_it():
    decision = decide(zones=[AISLE], robots=[robot("a"), robot("b", priority=5)], holders={AISLE_KEY: ["a"]})

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert decision.waiting == {"b": frozenset({AISLE_KEY})}


@pytest.mark.parametrize(
    ("a", "b", "first"),
    [
        ({"priority": 1}, {"priority": 2}, "b"),
        ({"priority": 2}, {"priority": 1}, "a"),
        ({"since": 2.0}, {"since": 1.0}, "b"),
        ({"since": 1.0}, {"since": 2.0}, "a"),
        ({"priority": 1, "since": 9.0}, {"since": 1.0}, "a"),  # priority before age
        ({}, {}, "a"),  # then the name
    ],
)
def test_the_zone_goes_by_priority_then_age(a, b, first):
    decision = decide(zones=[AISLE], robots=[robot("b", **b), robot("a", **a)], holders={})

    assert decision.holders == {AISLE_KEY: (first,)}


def test_a_zone_admits_its_capacity():
    wide = box("aisle", 2.0, -1.0, 4.0, 1.0, capacity=2)

    decision = decide(zones=[wide], robots=[robot(name, since=i) for i, name in enumerate("abc")], holders={})

    assert decision.holders == {AISLE_KEY: ("a", "b")}
    assert set(decision.waiting) == {"c"}


def test_a_robot_that_left_the_zone_lets_it_go_and_the_next_gets_it():
    past = robot("a", route=line(6.0), start=at(5.0, 0.0))  # beyond the aisle

    decision = decide(zones=[AISLE], robots=[past, robot("b")], holders={AISLE_KEY: ["a"]})

    assert decision.holders == {AISLE_KEY: ("b",)}


def test_a_robot_no_longer_counted_holds_nothing():
    """Deleted, or offline past its heartbeat timeout: the caller leaves it out."""
    decision = decide(zones=[AISLE], robots=[robot("b")], holders={AISLE_KEY: ["gone"]})

    assert decision.holders == {AISLE_KEY: ("b",)}


def test_the_released_base_keeps_its_zones_and_is_never_taken_back():
    """A robot whose base already goes into the zone keeps it though it has not reached it yet."""
    committed = robot("a", released=2)

    decision = decide(zones=[AISLE], robots=[committed], holders={AISLE_KEY: ["a"]})
    lost = decide(zones=[], robots=[robot("a", released=2)], holders={AISLE_KEY: ["a"]})

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert lost.horizons == {"a": 4} and lost.holders == {}  # the zone is gone: nothing holds it back
    standing = robot("x", route=(), start=at(3.0, 0.5))
    crowded = decide(zones=[AISLE], robots=[standing, robot("a", released=2)], holders={AISLE_KEY: ["x"]})
    assert crowded.holders == {AISLE_KEY: ("x", "a")}  # its base goes in: a fact, over capacity
    assert crowded.horizons["a"] == 4


def test_a_robot_inside_a_zone_holds_it_whatever_its_capacity():
    inside = robot("b", route=line(5.0), start=at(3.0, 0.0))

    decision = decide(zones=[AISLE], robots=[inside], holders={AISLE_KEY: ["a"]})
    both = decide(zones=[AISLE], robots=[robot("a", released=2), inside], holders={AISLE_KEY: ["a"]})

    assert decision.holders == {AISLE_KEY: ("b",)}
    assert both.holders == {AISLE_KEY: ("a", "b")}


def test_a_later_robot_does_not_overtake_one_that_waits_for_the_same_zone():
    """c wants only the free door, but b, served before c, waits for the aisle and the door together."""
    door = box("door", 2.0, 4.0, 4.0, 6.0)
    both = robot("b", route=(at(3.0, 0.0), at(3.0, 5.0), at(3.0, 8.0)), start=at(3.0, -3.0), since=1.0)
    only_door = robot("c", route=line(1.0, 3.0, 5.0, y=5.0), start=at(0.0, 5.0), since=2.0)
    # a robot that stands in the aisle, so that b cannot have it yet
    standing = robot("a", route=(), start=at(3.0, 0.5))

    decision = decide(zones=[AISLE, door], robots=[standing, both, only_door], holders={})

    assert decision.waiting == {
        "b": frozenset({AISLE_KEY, (MAP, "door")}),
        "c": frozenset({(MAP, "door")}),
    }
    assert decision.horizons["c"] == 1


def test_adjacent_zones_are_one_leg_granted_all_at_once_or_not_at_all():
    """No node between two touching zones lies outside both: a robot could not wait between them, so it
    gets both or neither."""
    left, right = box("left", 2.0, -1.0, 3.0, 1.0), box("right", 3.0, -1.0, 4.0, 1.0)
    crossing = robot("a", route=line(1.0, 2.5, 3.5, 5.0))
    blocker = robot("x", route=(), start=at(3.5, 0.5))  # stands in the right one

    granted = decide(zones=[left, right], robots=[crossing], holders={})
    blocked = decide(zones=[left, right], robots=[blocker, crossing], holders={})

    assert granted.holders == {(MAP, "left"): ("a",), (MAP, "right"): ("a",)}
    assert granted.horizons["a"] == 4
    assert blocked.holders == {(MAP, "right"): ("x",)}  # a does not take the left one alone
    assert blocked.horizons["a"] == 1


def test_an_edge_that_cuts_a_zone_needs_it_though_no_node_is_inside():
    decision = decide(
        zones=[AISLE], robots=[robot("a", route=line(1.0, 5.0)), robot("b", since=1.0)], holders={}
    )

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert decision.horizons == {"a": 2, "b": 1}


def test_zones_of_another_map_are_not_in_the_way():
    other = box("aisle", 2.0, -1.0, 4.0, 1.0, map_id="yard")

    decision = decide(zones=[other], robots=[robot("a"), robot("b")], holders={})

    assert decision.holders == {} and decision.horizons == {"a": 4, "b": 4}


def test_3_0_robots_are_answered_for_each_request():
    asks = robot(
        "a",
        requests=(ZoneRequest("r1", MAP, "aisle"), ZoneRequest("r2", MAP, "nowhere")),
    )
    later = robot("b", since=1.0, requests=(ZoneRequest("r3", MAP, "aisle"),))

    decision = decide(zones=[AISLE], robots=[asks, later], holders={})

    assert decision.responses == {
        "a": (("r1", GrantType.GRANTED), ("r2", GrantType.REJECTED)),
        "b": (("r3", GrantType.QUEUED),),
    }


def test_a_3_0_robot_without_a_route_of_ours_gets_what_it_asks_for_and_keeps_it_while_it_asks():
    free_roaming = RobotRoute(robot="a", position=at(0.0, 0.0), requests=(ZoneRequest("r1", MAP, "aisle"),))

    first = decide(zones=[AISLE], robots=[free_roaming], holders={})
    again = decide(zones=[AISLE], robots=[free_roaming], holders=first.holders)
    done = decide(zones=[AISLE], robots=[RobotRoute(robot="a", position=at(0.0, 0.0))], holders=again.holders)

    assert first.holders == again.holders == {AISLE_KEY: ("a",)}
    assert done.holders == {}


def test_geometry_of_routes_nodes_and_edges():
    assert list(zones_at(at(3.0, 0.0), [AISLE])) == [AISLE_KEY]
    assert list(zones_at(at(3.0, 0.0, "yard"), [AISLE])) == []
    assert list(zones_on(at(0.0, 0.0), at(6.0, 0.0), [AISLE])) == [AISLE_KEY]
    assert list(zones_on(at(0.0, 5.0), at(6.0, 5.0), [AISLE])) == []
    assert list(zones_on(None, at(3.0, 0.0), [AISLE])) == [AISLE_KEY]
    assert list(zones_on(at(3.0, 0.0, "yard"), at(0.0, 0.0), [AISLE])) == []  # a map change: only the end
    # The straight line passes above the aisle; the L along X, then Y (Isaac's simulator) goes through it.
    assert list(zones_on(at(0.0, 0.9), at(5.0, 5.0), [AISLE])) == [AISLE_KEY]


# --- driving: robots follow their horizons while the core decides each tick ------------------------------


@dataclass
class Driving:
    """Robots driving their routes node by node, as far as the core lets each go."""

    zones: list[Zone]
    routes: dict[str, list[RoutePoint]]
    priorities: dict[str, int] = field(default_factory=dict)
    speeds: random.Random | None = None  # None: every robot that may move does; else each tick at random
    position: dict[str, RoutePoint] = field(init=False)
    ahead: dict[str, list[RoutePoint]] = field(init=False)
    released: dict[str, int] = field(init=False)
    holders: dict[ZoneKey, tuple[str, ...]] = field(init=False, default_factory=dict)
    inside_together: list[tuple[int, ZoneKey, set[str]]] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        self.position = {name: route[0] for name, route in self.routes.items()}
        self.ahead = {name: list(route[1:]) for name, route in self.routes.items()}
        self.released = dict.fromkeys(self.routes, 0)

    def tick(self, number: int) -> bool | None:
        """One decision and one move each: whether a robot moved; None once every robot has arrived."""
        driving = [name for name in self.routes if self.ahead[name]]
        if not driving:
            return None
        moved = False
        decision = decide(
            zones=self.zones,
            robots=[
                RobotRoute(
                    robot=name,
                    priority=self.priorities.get(name, 0),
                    since=float(index),
                    position=self.position[name],
                    route=tuple(self.ahead[name]),
                    released=self.released[name],
                )
                for index, name in enumerate(self.routes)
                if self.ahead[name]
            ],
            holders=self.holders,
        )
        self.holders = decision.holders
        by_key = {zone.key: zone for zone in self.zones}
        for key, names in decision.holders.items():
            assert len(names) <= by_key[key].capacity, (number, key, names)
        occupied: dict[ZoneKey, set[str]] = {}
        for name in driving:
            horizon = decision.horizons[name]
            assert horizon >= self.released[name]
            moves = horizon > 0 and (self.speeds is None or self.speeds.random() < 0.7)
            if moves:
                start, end = self.position[name], self.ahead[name][0]
                crossed = set(zones_on(start, end, self.zones))
                owned = {key for key, names in decision.holders.items() if name in names}
                assert crossed <= owned, (number, name, crossed, owned)
                self.position[name], self.ahead[name] = end, self.ahead[name][1:]
                self.released[name] = horizon - 1
                moved = True
            else:
                crossed = set(zones_at(self.position[name], self.zones))
                self.released[name] = horizon
            for key in crossed:
                occupied.setdefault(key, set()).add(name)
        for key, names in occupied.items():
            if len(names) > by_key[key].capacity:
                self.inside_together.append((number, key, names))
        return moved

    def run(self, ticks: int) -> int:
        """Ticks until every robot arrived; fails if they have not within `ticks`, or once none has moved
        for STALLED ticks (with random speeds, a robot that may move stays put that long only by a chance
        of 0.3**STALLED)."""
        still = 0
        for number in range(ticks):
            moved = self.tick(number)
            if moved is None:
                return number
            still = 0 if moved else still + 1
            if still == STALLED:
                break
        waiting = {name: self.position[name] for name in self.routes if self.ahead[name]}
        raise AssertionError(f"not arrived after {number + 1} ticks: {waiting}, holders {self.holders}")


def test_two_robots_crossing_two_separate_zones_in_opposite_orders_both_arrive():
    """a goes east through zone west then zone east; b goes west through them the other way; each can wait
    at x=5, between them."""
    west, east = box("west", 2.0, -1.0, 4.0, 1.0), box("east", 6.0, -1.0, 8.0, 1.0)
    routes = {"a": list(line(0, 1, 3, 5, 7, 9, 10)), "b": list(line(10, 9, 7, 5, 3, 1, 0))}

    driving = Driving([west, east], routes)
    driving.run(40)

    assert driving.inside_together == []


def test_two_robots_crossing_two_touching_zones_in_opposite_orders_both_arrive():
    """No node between the zones lies outside both: each robot gets both at once or waits outside."""
    west, east = box("west", 2.0, -1.0, 4.0, 1.0), box("east", 4.0, -1.0, 6.0, 1.0)
    routes = {"a": list(line(0, 1, 3, 5, 7, 8)), "b": list(line(8, 7, 5, 3, 1, 0))}

    driving = Driving([west, east], routes)
    ticks = driving.run(40)

    assert driving.inside_together == []
    assert ticks > 7  # one waited for the other: they could not both pass at once


SIDE = 6  # the grid's nodes: 0..SIDE on both axes, crowded enough for robots to meet in zones
STEPS = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1))
coordinate = st.integers(0, SIDE)
# A zone: a rectangle of 1 to 3 grid cells a side around a node, or a diamond (whose edges cut the
# grid's diagonals); capacity mostly 1.
zone_shapes = st.tuples(
    coordinate, coordinate, st.integers(1, 3), st.integers(1, 3), st.booleans(), st.sampled_from((1, 1, 1, 2))
)
# A route: a start node and a walk of 2 to 16 steps on the grid.
walks = st.tuples(coordinate, coordinate, st.lists(st.sampled_from(STEPS), min_size=2, max_size=16))


def _zone(number: int, shape: tuple[int, int, int, int, bool, int]) -> Zone:
    x, y, width, height, diamond, capacity = shape
    if diamond:
        r = width + 0.5
        return Zone(MAP, f"z{number}", ((x, y - r), (x + r, y), (x, y + r), (x - r, y)), capacity)
    return box(f"z{number}", x - 0.5, y - 0.5, x + width - 0.5, y + height - 0.5, capacity)


def _route(walk: tuple[int, int, list[tuple[int, int]]]) -> list[RoutePoint]:
    x, y, steps = walk
    points = [at(x, y)]
    for dx, dy in steps:
        x, y = min(SIDE, max(0, x + dx)), min(SIDE, max(0, y + dy))
        points.append(at(x, y))
    return points


@PROPERTIES
@given(
    shapes=st.lists(zone_shapes, min_size=1, max_size=8),
    walks=st.lists(walks, min_size=2, max_size=8),
    priorities=st.lists(st.sampled_from((0, 0, 1, 5)), min_size=8, max_size=8),
    speeds=st.none() | st.integers(0, 2**32 - 1),
)
def test_random_fleets_never_crowd_a_zone_and_all_arrive(shapes, walks, priorities, speeds):
    """Robots start and end outside every zone (one that ends inside keeps it, rightly, for ever)."""
    zones = [_zone(number, shape) for number, shape in enumerate(shapes)]
    routes = {
        f"r{number}": route
        for number, route in enumerate(_route(walk) for walk in walks)
        if not any(True for _ in zones_at(route[0], zones))
        and not any(True for _ in zones_at(route[-1], zones))
    }
    driving = Driving(
        zones,
        routes,
        dict(zip(routes, priorities, strict=False)),
        speeds=None if speeds is None else random.Random(speeds),
    )

    # Even one robot at a time, each waiting now and then (random speeds), ends well within this.
    driving.run(60 * len(walks) * 17)

    assert driving.inside_together == []


def test_a_revoked_grant_goes_to_the_next_robot_and_the_robot_is_told():
    asking = robot("a", requests=(ZoneRequest("r1", MAP, "aisle"),))
    granted = decide(zones=[AISLE], robots=[asking, robot("b", since=1.0)], holders={})

    revoked = decide(
        zones=[AISLE],
        robots=[asking, robot("b", since=1.0)],
        holders=granted.holders,
        revoked=[("a", AISLE_KEY)],
    )
    later = decide(zones=[AISLE], robots=[asking, robot("b", since=1.0)], holders=revoked.holders)

    assert granted.holders == {AISLE_KEY: ("a",)}
    assert revoked.holders == {AISLE_KEY: ("b",)}
    assert revoked.responses == {"a": (("r1", GrantType.REVOKED),)}
    assert (revoked.horizons["a"], revoked.waiting["a"]) == (1, frozenset({AISLE_KEY}))
    assert later.holders == {AISLE_KEY: ("b",)} and later.responses == {"a": (("r1", GrantType.QUEUED),)}


def test_a_robot_inside_keeps_a_revoked_zone_until_it_has_left():
    inside = robot("a", route=line(5.0), start=at(3.0, 0.0), requests=(ZoneRequest("r1", MAP, "aisle"),))

    decision = decide(
        zones=[AISLE], robots=[inside, robot("b")], holders={AISLE_KEY: ["a"]}, revoked=[("a", AISLE_KEY)]
    )

    assert decision.holders == {AISLE_KEY: ("a",)}
    assert decision.responses == {"a": (("r1", GrantType.REVOKED),)}
    assert decision.waiting == {"b": frozenset({AISLE_KEY})}


def test_a_3_0_robots_zone_requests_are_read_against_the_enabled_zone_sets():
    def request(request_id: str, zone_set_id: str = "floor1-v2", **fields) -> Request:
        values = {"request_type": "ACCESS", "request_status": "REQUESTED", "zone_id": "aisle", **fields}
        return Request(request_id=request_id, zone_set_id=zone_set_id, **values)

    taken, rejected = zone_requests(
        [
            request("r1"),
            request("r2", request_status="GRANTED"),
            request("r3", zone_set_id="floor1-v1"),  # an older set of the map
            request("r4", request_type="REPLANNING"),
            request("r5", request_status="EXPIRED"),
        ],
        {MAP: "floor1-v2", "yard": "yard-v1"},
    )

    assert taken == (ZoneRequest("r1", MAP, "aisle"), ZoneRequest("r2", MAP, "aisle"))
    assert rejected == ("r3", "r4")
