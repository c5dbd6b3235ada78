"""Access to RELEASE zones: who holds each zone, who waits, and how far each robot's order may reach.
Pure: the robots (their positions and the route nodes still ahead), the zones and the current holders in;
the new holders, each robot's horizon and the answers to 3.0 robots' zone requests out.

The rules, in the order `decide` applies them:

- A robot holds a zone while it is inside it, while its order's base (the `released` nodes ahead) or the
  legs ahead it holds whole still cross it, or while it (3.0) still asks for it. Any other grant is let
  go: the robot has left the zone. A robot inside a zone, or whose released base crosses it, holds it
  whatever the capacity: that is where it is, or goes (a base is never taken back).
- A route is cut into *legs*, each ending at the first node that lies in no zone (a place the robot may
  wait without being in anyone's way) or at the route's end. A robot only ever asks for the zones of its
  next leg it does not hold, all of them at once: it gets all or none. So a robot waiting at a zone's
  edge holds nothing (it waits at a node outside every zone), and no waiting robot holds what another
  waits for: there is no cycle of robots waiting for each other, whatever the routes and zones
  (tests/dispatch/test_zones.py checks it over random layouts).
- Requests are served by mission priority (higher first), then age (older first), then robot name. A zone
  an earlier robot waits for is not given to a later one even if it has room, so no robot waits for ever
  behind a stream of later ones.
- A zone admits `capacity` robots at once (1 unless the zone says more, our setting).
- An operator may revoke a grant: a robot not yet in the zone loses it (and waits, without holding others
  up, until the next decision queues it again); one already in it is answered REVOKED and holds the zone
  until it has left.
- A robot's horizon is how many of its route nodes its order's base may hold: through every leg whose
  zones it holds, never fewer than the nodes already released (a base is never taken back).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from vda5050.models import Request
from vda5050.polygons import Point, box_touches, contains
from vda5050.zones import GrantType, RequestStatus, RequestType

ZoneKey = tuple[str, str]  # (map_id, zone_id): zone ids are unique within a map's zone set


@dataclass(frozen=True)
class Zone:
    """A RELEASE zone of a map's enabled zone set."""

    map_id: str
    zone_id: str
    vertices: tuple[Point, ...]
    capacity: int = 1

    @property
    def key(self) -> ZoneKey:
        return self.map_id, self.zone_id


@dataclass(frozen=True)
class RoutePoint:
    x: float
    y: float
    map_id: str

    @property
    def point(self) -> Point:
        return self.x, self.y


@dataclass(frozen=True)
class ZoneRequest:
    """A 3.0 robot's request for access to a zone (state ``zoneRequests``, type ACCESS)."""

    request_id: str
    map_id: str
    zone_id: str

    @property
    def key(self) -> ZoneKey:
        return self.map_id, self.zone_id


@dataclass(frozen=True)
class RobotRoute:
    """What the core knows of a robot: where it is, the nodes its mission's route still goes to (in order,
    the next one first), how many of those its order's base already holds, and who it works for."""

    robot: str
    priority: int = 0  # its mission's: higher first
    since: float = 0.0  # its mission's age as a sortable number (earlier: smaller, served first)
    position: RoutePoint | None = None
    route: tuple[RoutePoint, ...] = ()
    released: int = 0
    requests: tuple[ZoneRequest, ...] = ()


@dataclass(frozen=True)
class ZoneDecision:
    holders: dict[ZoneKey, tuple[str, ...]]  # each zone's robots, in the order they got it
    horizons: dict[str, int]  # robot -> route nodes its base may hold
    waiting: dict[str, frozenset[ZoneKey]]  # robot -> the zones it waits for (all at once)
    responses: dict[str, tuple[tuple[str, GrantType], ...]]  # 3.0 robot -> (requestId, grantType)


def decide(
    *,
    zones: Iterable[Zone],
    robots: Iterable[RobotRoute],
    holders: Mapping[ZoneKey, Iterable[str]],
    revoked: Iterable[tuple[str, ZoneKey]] = (),
) -> ZoneDecision:
    """Who holds which zone now, how far each robot may go and what 3.0 robots are answered; see the module
    docstring for the rules. `robots` are the robots that count (a robot left out, deleted or offline
    past its heartbeat timeout, holds nothing any more; a 3.0 request whose lease EXPIRED is left out of
    its requests). `revoked`: grants an operator takes back, (robot, zone)."""
    by_key = {zone.key: zone for zone in zones}
    routes = sorted(robots, key=lambda robot: (-robot.priority, robot.since, robot.robot))
    paths = {robot.robot: _Path.of(robot, by_key) for robot in routes}
    revocations = frozenset(revoked)
    held = _kept(holders, routes, paths, by_key, revocations)
    owned = _owned(held, routes)

    waiting: dict[str, frozenset[ZoneKey]] = {}
    waited_for: set[ZoneKey] = set()
    for robot in routes:
        wanted = paths[robot.robot].wanted(owned[robot.robot]) | {
            request.key
            for request in robot.requests
            if request.key in by_key and request.key not in owned[robot.robot]
        }
        if not wanted:
            continue
        if any((robot.robot, key) in revocations for key in wanted):
            waiting[robot.robot] = frozenset(wanted)  # not given back at once; it waits without blocking
            continue
        if wanted.isdisjoint(waited_for) and all(len(held[key]) < by_key[key].capacity for key in wanted):
            for key in sorted(wanted):
                held[key].append(robot.robot)
            owned[robot.robot] |= wanted
            continue
        waiting[robot.robot] = frozenset(wanted)
        waited_for |= wanted

    return ZoneDecision(
        holders={key: tuple(names) for key, names in held.items() if names},
        horizons={robot.robot: paths[robot.robot].horizon(owned[robot.robot]) for robot in routes},
        waiting=waiting,
        responses={
            robot.robot: tuple(
                (
                    request.request_id,
                    _answer(robot.robot, request.key, owned[robot.robot], by_key, revocations),
                )
                for request in robot.requests
            )
            for robot in routes
            if robot.requests
        },
    )


@dataclass(frozen=True)
class _Path:
    """A robot's route as zones: those it is in, those each node's approach touches, and its legs."""

    released: int
    inside: frozenset[ZoneKey]
    touched: tuple[frozenset[ZoneKey], ...]  # per route node: zones its node or the edge to it touches
    leg_ends: tuple[int, ...]  # the index of each leg's last node

    @classmethod
    def of(cls, robot: RobotRoute, zones: Mapping[ZoneKey, Zone]) -> _Path:
        inside = frozenset(zones_at(robot.position, zones.values())) if robot.position else frozenset()
        touched = []
        previous = robot.position
        for node in robot.route:
            touched.append(frozenset(zones_on(previous, node, zones.values())))
            previous = node
        free = [not any(True for _ in zones_at(node, zones.values())) for node in robot.route]
        leg_ends = tuple(i for i, is_free in enumerate(free) if is_free or i == len(free) - 1)
        return cls(min(robot.released, len(robot.route)), inside, tuple(touched), leg_ends)

    def forced(self) -> frozenset[ZoneKey]:
        """Zones the robot is in or its released base still crosses."""
        return self.inside.union(*self.touched[: self.released])

    def _legs(self) -> Iterable[tuple[int, frozenset[ZoneKey]]]:
        start = 0
        for end in self.leg_ends:
            yield end, frozenset().union(*self.touched[start : end + 1])
            start = end + 1

    def wanted(self, owned: frozenset[ZoneKey] | set[ZoneKey]) -> frozenset[ZoneKey]:
        """The zones of its first leg it does not fully hold, that it does not hold."""
        for _, zones in self._legs():
            if not zones <= owned:
                return zones - owned
        return frozenset()

    def horizon(self, owned: frozenset[ZoneKey] | set[ZoneKey]) -> int:
        reach = 0
        for end, zones in self._legs():
            if not zones <= owned:
                break
            reach = end + 1
        return max(reach, self.released)


def _kept(
    holders: Mapping[ZoneKey, Iterable[str]],
    routes: list[RobotRoute],
    paths: Mapping[str, _Path],
    zones: Mapping[ZoneKey, Zone],
    revocations: frozenset[tuple[str, ZoneKey]],
) -> dict[ZoneKey, list[str]]:
    """The grants that still stand (not revoked), and a grant for every zone a robot is in or its released
    base crosses (facts no decision or revocation undoes, whatever the capacity)."""
    previous: dict[str, set[ZoneKey]] = {robot.robot: set() for robot in routes}
    for key, names in holders.items():
        for name in names:
            if name in previous and key in zones:
                previous[name].add(key)
    keep = {
        robot.robot: _still_needed(paths[robot.robot], previous[robot.robot])
        | {request.key for request in robot.requests}
        for robot in routes
    }
    held: dict[ZoneKey, list[str]] = {key: [] for key in zones}
    for key, names in holders.items():
        for name in dict.fromkeys(names):
            if key in held and name in keep and key in keep[name] and (name, key) not in revocations:
                held[key].append(name)
    for robot in routes:
        for key in sorted(paths[robot.robot].forced()):
            if robot.robot not in held[key]:
                held[key].append(robot.robot)
    return held


def _still_needed(path: _Path, previous: set[ZoneKey]) -> frozenset[ZoneKey]:
    """A robot's grants that still stand: the zones it is in, and those of the route it may still drive
    with them (its released base, and the legs ahead it holds whole)."""
    return path.inside.union(*path.touched[: path.horizon(previous)])


def _owned(held: Mapping[ZoneKey, list[str]], routes: list[RobotRoute]) -> dict[str, set[ZoneKey]]:
    owned: dict[str, set[ZoneKey]] = {robot.robot: set() for robot in routes}
    for key, names in held.items():
        for name in names:
            owned[name].add(key)
    return owned


def _answer(
    robot: str,
    key: ZoneKey,
    owned: set[ZoneKey],
    zones: Mapping[ZoneKey, Zone],
    revocations: frozenset[tuple[str, ZoneKey]],
) -> GrantType:
    if key not in zones:
        return GrantType.REJECTED  # no RELEASE zone of that id in its map's enabled set
    if (robot, key) in revocations:
        return GrantType.REVOKED  # one inside still holds it until it has left (VDA 5050)
    return GrantType.GRANTED if key in owned else GrantType.QUEUED


def zone_requests(
    requests: Iterable[Request], enabled: Mapping[str, str]
) -> tuple[tuple[ZoneRequest, ...], tuple[str, ...]]:
    """A 3.0 robot's state ``zoneRequests`` as the core takes them, and the requestIds to answer REJECTED at
    once: another request type than ACCESS, or a zone set that is not its map's enabled one (`enabled`:
    mapId -> zoneSetId). A request whose lease EXPIRED is left out: the robot holds nothing by it."""
    maps = {zone_set_id: map_id for map_id, zone_set_id in enabled.items()}
    taken: list[ZoneRequest] = []
    rejected: list[str] = []
    for request in requests:
        if not answerable(request):
            continue
        map_id = maps.get(request.zone_set_id or "")
        if request.request_type != RequestType.ACCESS or map_id is None:
            rejected.append(request.request_id)
        else:
            taken.append(ZoneRequest(request.request_id, map_id, request.zone_id))
    return tuple(taken), tuple(rejected)


def answerable(request: Request) -> bool:
    """A zone request the core answers (taken or REJECTED): one for a zone (an edge request names none) whose
    lease has not EXPIRED."""
    return request.request_status != RequestStatus.EXPIRED and request.zone_id is not None


def zones_at(point: RoutePoint, zones: Iterable[Zone]) -> Iterable[ZoneKey]:
    """The zones `point` lies in (its boundary included)."""
    return (
        zone.key for zone in zones if zone.map_id == point.map_id and contains(zone.vertices, point.point)
    )


def zones_on(start: RoutePoint | None, end: RoutePoint, zones: Iterable[Zone]) -> Iterable[ZoneKey]:
    """The zones a robot may touch going from `start` to `end` (only `end`'s, without a start or across
    maps). An edge without a trajectory leaves the path to the robot: straight, or L-shaped as Isaac's
    simulator drives; so the zones of the box the two nodes span count, not only those of the straight
    line (a long diagonal edge beside a zone waits for it too)."""
    if start is None or start.map_id != end.map_id:
        return zones_at(end, zones)
    return (
        zone.key
        for zone in zones
        if zone.map_id == end.map_id and box_touches(zone.vertices, start.point, end.point)
    )
