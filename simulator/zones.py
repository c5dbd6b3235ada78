"""Zones on a simulated 3.0 robot: the zone sets it holds and its access to RELEASE zones (VDA 5050 3.0,
6.4.2 and 6.4.3). Pure: ``simulator.robot`` feeds it messages and poses.

Zone sets arrive on the ``zoneSet`` topic, DISABLED; ``enableZoneSet`` enables one (and disables the other
sets of its map), ``deleteZoneSet`` deletes one. A set whose id the robot holds already is not taken
(``DUPLICATE_ZONE_SET``).

Before its route enters a RELEASE zone of an enabled set of its map, the robot puts an ACCESS request for
that zone in its state (``zoneRequests``, REQUESTED) and waits where it stands, at the last node before the
zone, until fleet control answers GRANTED on ``responses``. QUEUED and REJECTED leave it waiting; REVOKED
before it entered makes it wait for a new grant (the request is REQUESTED again); REVOKED once inside is
reported, and the robot drives on out (a robot that stopped inside would block the zone for good). A
request is dropped once the robot has left its zone, or, never entered, once the robot has no route left.
Lease expiry is not simulated: a grant lasts until the robot leaves.
"""

from __future__ import annotations

from dataclasses import dataclass

from simulator.actions import ActionRun, UnusableAction, parameters_of, require
from simulator.errors import ACTION_ERROR, DUPLICATE_ZONE_SET, UNKNOWN_ZONE_SET, VALIDATION_ERROR, ErrorReport
from simulator.outbox import Outbox
from vda5050.codec import parse_responses, parse_zone_set
from vda5050.errors import ProtocolError
from vda5050.models import ActionType, MapStatus, Request, ZoneSetDefinition, ZoneSetState
from vda5050.polygons import Point, Polygon, contains, segment_touches
from vda5050.topics import Topic
from vda5050.zones import ZONE_SET_ID, GrantType, RequestStatus, RequestType, ZoneType


@dataclass
class ZoneRequest:
    request_id: str
    zone_set_id: str
    zone_id: str
    polygon: Polygon
    status: str = RequestStatus.REQUESTED
    entered: bool = False

    def report(self) -> Request:
        return Request(
            request_id=self.request_id,
            request_type=RequestType.ACCESS,
            zone_id=self.zone_id,
            zone_set_id=self.zone_set_id,
            request_status=self.status,
        )


class RobotZones:
    """The robot's zone sets (zoneSetId -> set and status) and its zone requests (in request order)."""

    def __init__(self, *, serial: str, errors: ErrorReport, outbox: Outbox) -> None:
        self._serial = serial
        self._errors = errors
        self._outbox = outbox
        self._sets: dict[str, tuple[ZoneSetDefinition, MapStatus]] = {}
        self._requests: dict[str, ZoneRequest] = {}  # requestId -> request
        self._next_request = 0

    # --- zone sets ---------------------------------------------------------------------------------

    def receive_zone_set(self, payload: bytes) -> None:
        """A ``zoneSet`` message: the set is held, DISABLED, unless one of its id is already."""
        try:
            zone_set = parse_zone_set(payload).zone_set
        except ProtocolError as exc:
            self._errors.warn(VALIDATION_ERROR, str(exc), [("topic", Topic.ZONE_SET.value)])
            return
        if zone_set.zone_set_id in self._sets:
            self._errors.warn(
                DUPLICATE_ZONE_SET,
                f"zone set {zone_set.zone_set_id} is here already",
                [("zoneSetId", zone_set.zone_set_id)],
            )
            return
        self._sets[zone_set.zone_set_id] = (zone_set, MapStatus.DISABLED)
        self._outbox.state_changed = True

    def act(self, run: ActionRun) -> None:
        """enableZoneSet or deleteZoneSet."""
        try:
            zone_set_id = str(require(parameters_of(run.action), ZONE_SET_ID))
        except UnusableAction as exc:
            self._errors.refuse_action(run, ACTION_ERROR, str(exc))
            return
        held = self._sets.get(zone_set_id)
        if held is None:
            self._errors.refuse_action(run, UNKNOWN_ZONE_SET, f"zone set {zone_set_id} is not here")
            return
        if run.action.action_type == ActionType.ENABLE_ZONE_SET:
            map_id = held[0].map_id
            for other_id, (other, _) in self._sets.items():
                if other.map_id == map_id:
                    status = MapStatus.ENABLED if other_id == zone_set_id else MapStatus.DISABLED
                    self._sets[other_id] = (other, status)
            run.finish(f"zone set {zone_set_id} enabled")
        else:
            del self._sets[zone_set_id]
            self._requests = {k: r for k, r in self._requests.items() if r.zone_set_id != zone_set_id}
            run.finish(f"zone set {zone_set_id} deleted")
        self._outbox.state_changed = True

    def report(self) -> list[ZoneSetState]:
        """The state's ``zoneSets``."""
        return [
            ZoneSetState(zone_set_id=zone_set_id, map_id=zone_set.map_id, zone_set_status=status)
            for zone_set_id, (zone_set, status) in self._sets.items()
        ]

    # --- access to RELEASE zones ---------------------------------------------------------------------

    def receive_responses(self, payload: bytes) -> None:
        """Fleet control's answers to the robot's requests; answers to requests it no longer has are
        ignored."""
        try:
            responses = parse_responses(payload).responses
        except ProtocolError as exc:
            self._errors.warn(VALIDATION_ERROR, str(exc), [("topic", Topic.RESPONSES.value)])
            return
        for response in responses:
            request = self._requests.get(response.request_id)
            if request is None:
                continue
            status = answered(request, response.grant_type)
            if status != request.status:
                request.status = status
                self._outbox.state_changed = True

    def requests(self) -> list[Request]:
        """The state's ``zoneRequests``."""
        return [request.report() for request in self._requests.values()]

    def may_drive(self, map_id: str, here: Point, to: Point) -> bool:
        """Whether the robot may drive from `here` towards `to`: every RELEASE zone of its map's enabled
        sets that the way enters (one it stands in is entered already) is granted; a request is made for
        each that is not."""
        may = True
        for zone_set_id, zone_id, polygon in self._release_zones(map_id):
            if contains(polygon, here) or not segment_touches(polygon, here, to):
                continue
            request = self._request_for(zone_set_id, zone_id, polygon)
            may = may and request.status == RequestStatus.GRANTED
        return may

    def moved(self, here: Point, *, route_left: bool) -> None:
        """The robot is at `here`: requests whose zone it entered and left again are dropped, and, once it
        has no route left, those it never entered."""
        kept = {}
        for request_id, request in self._requests.items():
            within = contains(request.polygon, here)
            request.entered = request.entered or within
            if (request.entered and not within) or (not route_left and not request.entered):
                self._outbox.state_changed = True
                continue
            kept[request_id] = request
        self._requests = kept

    def _release_zones(self, map_id: str) -> list[tuple[str, str, Polygon]]:
        return [
            (zone_set_id, zone.zone_id, [(v.x, v.y) for v in zone.vertices])
            for zone_set_id, (zone_set, status) in self._sets.items()
            if status == MapStatus.ENABLED and zone_set.map_id == map_id
            for zone in zone_set.zones
            if zone.zone_type == ZoneType.RELEASE
        ]

    def _request_for(self, zone_set_id: str, zone_id: str, polygon: Polygon) -> ZoneRequest:
        for request in self._requests.values():
            if (request.zone_set_id, request.zone_id) == (zone_set_id, zone_id):
                return request
        self._next_request += 1
        request = ZoneRequest(f"{self._serial}-zone-{self._next_request}", zone_set_id, zone_id, polygon)
        self._requests[request.request_id] = request
        self._outbox.state_changed = True
        return request


def answered(request: ZoneRequest, grant_type: str) -> str:
    """A request's status after fleet control's answer."""
    match grant_type:
        case GrantType.GRANTED:
            return RequestStatus.GRANTED
        case GrantType.REVOKED if request.entered:
            return RequestStatus.REVOKED  # reported; the robot drives on out
        case GrantType.REVOKED:
            return RequestStatus.REQUESTED  # not yet in: wait for a new grant
        case _:  # QUEUED, REJECTED: as it was (waiting)
            return request.status
