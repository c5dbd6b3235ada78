"""Zone sets on a 3.0 robot: which ones the fleet wants it to hold, and the next move towards that. Pure.

Fleet control alone distributes zone sets (VDA 5050 3.0, 6.4.2). A robot that takes zone sets (VDA 5050
3.0, its factsheet lists `supportedZones`) should hold, ENABLED, the fleet's enabled zone set of each map
it is on (the maps it reports and the one its pose is on), and no set the fleet has not enabled. One move
at a time per set, each as the standard prescribes it:

- the robot lacks the set: the set's `zoneSet` message, which the robot adds DISABLED;
- it holds the set DISABLED: `enableZoneSet` (the robot disables the map's other set itself);
- it holds a set the fleet has not enabled (disabled or deleted since): `deleteZoneSet`.

A move is made once. It is made again only if the robot's state still asks for it `resend` after the
robot's last move (a lost message, a failed action: instant actions not yet answered are resent by the
step itself). The moves made are remembered per set until the set is where it should be; they change, and
are written, only when a move is made or done, never per state.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import StrEnum

from dispatch.records import ActionRecord
from vda5050 import orders
from vda5050.models import ActionType, MapStatus, State
from vda5050.zones import ZONE_SET_ID


class Move(StrEnum):
    """A move towards the zone sets a robot should hold: the message or action that makes it."""

    SEND = "zoneSet"
    ENABLE = ActionType.ENABLE_ZONE_SET.value
    DELETE = ActionType.DELETE_ZONE_SET.value


@dataclass(frozen=True)
class ZoneSetMoves:
    """The moves made and not yet seen done (zoneSetId -> Move), and when the robot's last move was made."""

    made: Mapping[str, str] = field(default_factory=dict)
    at: datetime | None = None


@dataclass
class ZoneSetPlan:
    """What a step does for the robot's zone sets: the sets whose `zoneSet` message goes out now, the new
    instant actions, and the moves to remember."""

    send: list[str]
    actions: list[ActionRecord]
    moves: ZoneSetMoves


def plan_zone_sets(
    *,
    robot: str,
    enabled: Mapping[str, str],
    moves: ZoneSetMoves,
    state: State | None,
    online: bool,
    actions: list[ActionRecord],
    now: datetime,
    resend: timedelta,
) -> ZoneSetPlan:
    """The next moves for a robot that takes zone sets. `enabled` is the fleet's enabled set of each map
    (mapId -> zoneSetId); `actions` the robot's instant actions not yet final. Nothing is decided without a
    state to go by, nor sent to a robot offline (it gets its sets once back)."""
    plan = ZoneSetPlan(send=[], actions=[], moves=moves)
    if state is None or not online:
        return plan
    held = {zone_set.zone_set_id: zone_set.zone_set_status for zone_set in state.zone_sets or ()}
    wanted_moves = _wanted_moves(held, _wanted(enabled, state), set(enabled.values()))
    pending = {
        (action.action_type, (action.parameters or {}).get(ZONE_SET_ID))
        for action in actions
        if action.action_type in (Move.ENABLE, Move.DELETE)
    }
    made: dict[str, str] = {}
    moved_at = moves.at
    retry = moves.at is None or now - moves.at >= resend
    for zone_set_id, move in wanted_moves.items():
        made[zone_set_id] = move
        if (move, zone_set_id) in pending or (moves.made.get(zone_set_id) == move and not retry):
            continue  # under way
        moved_at = now
        if move == Move.SEND:
            plan.send.append(zone_set_id)
        else:
            plan.actions.append(
                ActionRecord(
                    action_id=orders.new_action_id(f"{robot}-{move}"),
                    action_type=move,
                    mission=None,
                    status=None,
                    sent_at=None,
                    parameters={ZONE_SET_ID: zone_set_id},
                )
            )
    if made != moves.made or moved_at != moves.at:
        plan.moves = ZoneSetMoves(made, moved_at)
    return plan


def _wanted(enabled: Mapping[str, str], state: State) -> list[str]:
    """The fleet's enabled sets of the maps the robot is on, in map order."""
    maps = {m.map_id for m in state.maps or ()}
    if state.agv_position is not None:
        maps.add(state.agv_position.map_id)
    return [enabled[map_id] for map_id in sorted(maps) if map_id in enabled]


def _wanted_moves(held: Mapping[str, MapStatus], wanted: list[str], fleet_sets: set[str]) -> dict[str, Move]:
    """zoneSetId -> the move it needs; enables before deletes, so that a robot taking both in one message
    switches a map's set over before deleting the old one."""
    moves: dict[str, Move] = {}
    for zone_set_id in wanted:
        status = held.get(zone_set_id)
        if status is None:
            moves[zone_set_id] = Move.SEND
        elif status != MapStatus.ENABLED:
            moves[zone_set_id] = Move.ENABLE
    for zone_set_id in sorted(held):
        if zone_set_id not in fleet_sets:
            moves[zone_set_id] = Move.DELETE
    return moves
