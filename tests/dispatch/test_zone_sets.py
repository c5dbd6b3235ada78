"""`dispatch.zone_sets.plan_zone_sets`: which zone set moves a step makes for a 3.0 robot, table-driven."""

from datetime import timedelta

import pytest

from dispatch.records import ActionRecord
from dispatch.zone_sets import Move, ZoneSetMoves, ZoneSetPlan, plan_zone_sets
from tests.dispatch.builders import NOW, robot_state
from vda5050.models import Map, MapStatus, State, ZoneSetState
from vda5050.zones import ZONE_SET_ID

RESEND = timedelta(seconds=5)
ENABLED, DISABLED = MapStatus.ENABLED, MapStatus.DISABLED


def state(*held: tuple[str, str, MapStatus], maps: tuple[str, ...] = (), pose_map: str = "map") -> State:
    """A state whose robot is on `pose_map`, reports `maps` and holds the zone sets (id, mapId, status)."""
    return robot_state(pose=(0.0, 0.0, 0.0, pose_map)).model_copy(
        update={
            "maps": [Map(map_id=m, map_version="1", map_status=ENABLED) for m in maps] or None,
            "zone_sets": [ZoneSetState(zone_set_id=i, map_id=m, zone_set_status=s) for i, m, s in held],
        }
    )


def plan(
    robot_state: State | None,
    enabled: dict[str, str],
    *,
    moves: ZoneSetMoves | None = None,
    actions: list[ActionRecord] | None = None,
    online: bool = True,
    after: float = 0.0,
) -> ZoneSetPlan:
    return plan_zone_sets(
        robot="r1",
        enabled=enabled,
        moves=moves or ZoneSetMoves(),
        state=robot_state,
        online=online,
        actions=actions or [],
        now=NOW + timedelta(seconds=after),
        resend=RESEND,
    )


def moves_of(result: ZoneSetPlan) -> list[tuple[str, str]]:
    """(zoneSetId, move) of what the plan sends and asks, in order."""
    sent = [(zone_set_id, Move.SEND.value) for zone_set_id in result.send]
    return sent + [(a.parameters[ZONE_SET_ID], a.action_type) for a in result.actions]


@pytest.mark.parametrize(
    ("robot_state", "enabled", "expected"),
    [
        # lacks the enabled set of its map: the zoneSet message
        (state(), {"map": "s1"}, [("s1", "zoneSet")]),
        # holds it DISABLED (the message arrived): enable it
        (state(("s1", "map", DISABLED)), {"map": "s1"}, [("s1", "enableZoneSet")]),
        # holds it ENABLED: nothing
        (state(("s1", "map", ENABLED)), {"map": "s1"}, []),
        # the set of a map it is not on: nothing
        (state(), {"hall": "s9"}, []),
        # a map it reports, though it stands on another: that map's set too
        (state(maps=("map", "hall")), {"map": "s1", "hall": "s9"}, [("s9", "zoneSet"), ("s1", "zoneSet")]),
        # the fleet disabled the set it holds: delete it
        (state(("s1", "map", ENABLED)), {}, [("s1", "deleteZoneSet")]),
        # switched over: enable the new before deleting the old
        (
            state(("s1", "map", ENABLED), ("s2", "map", DISABLED)),
            {"map": "s2"},
            [("s2", "enableZoneSet"), ("s1", "deleteZoneSet")],
        ),
        # the fleet's enabled set of another map, held: left alone
        (state(("s9", "hall", ENABLED)), {"hall": "s9"}, []),
    ],
)
def test_each_set_gets_the_move_it_needs(
    robot_state: State, enabled: dict[str, str], expected: list[tuple[str, str]]
) -> None:
    assert moves_of(plan(robot_state, enabled)) == expected


def test_a_move_is_remembered_and_not_made_again_until_the_resend_period_passed() -> None:
    first = plan(state(), {"map": "s1"})
    assert first.moves == ZoneSetMoves({"s1": Move.SEND}, NOW)

    again = plan(state(), {"map": "s1"}, moves=first.moves, after=RESEND.total_seconds() - 1)
    assert (moves_of(again), again.moves) == ([], first.moves)

    late = plan(state(), {"map": "s1"}, moves=first.moves, after=RESEND.total_seconds())
    assert moves_of(late) == [("s1", "zoneSet")]
    assert late.moves.at == NOW + RESEND


def test_the_next_move_of_a_set_is_made_at_once() -> None:
    sent = plan(state(), {"map": "s1"}).moves

    arrived = plan(state(("s1", "map", DISABLED)), {"map": "s1"}, moves=sent, after=1)

    assert moves_of(arrived) == [("s1", "enableZoneSet")]
    assert arrived.moves == ZoneSetMoves({"s1": Move.ENABLE}, NOW + timedelta(seconds=1))


def test_an_action_not_yet_final_is_not_asked_for_twice_even_after_the_resend_period() -> None:
    asked = plan(state(("s1", "map", DISABLED)), {"map": "s1"})
    [enable] = asked.actions
    assert (enable.action_type, enable.parameters, enable.sent_at) == (
        "enableZoneSet",
        {"zoneSetId": "s1"},
        None,
    )

    later = plan(state(("s1", "map", DISABLED)), {"map": "s1"}, moves=asked.moves, actions=[enable], after=60)

    assert moves_of(later) == []


def test_a_failed_action_is_asked_for_again_after_the_resend_period() -> None:
    asked = plan(state(("s1", "map", DISABLED)), {"map": "s1"})

    assert moves_of(plan(state(("s1", "map", DISABLED)), {"map": "s1"}, moves=asked.moves, after=1)) == []
    retried = plan(state(("s1", "map", DISABLED)), {"map": "s1"}, moves=asked.moves, after=5)
    assert moves_of(retried) == [("s1", "enableZoneSet")]


def test_moves_are_forgotten_once_done_and_unchanged_moves_are_the_same_object() -> None:
    sent = plan(state(), {"map": "s1"}).moves

    done = plan(state(("s1", "map", ENABLED)), {"map": "s1"}, moves=sent, after=1)
    assert done.moves == ZoneSetMoves({}, NOW)

    settled = plan(state(("s1", "map", ENABLED)), {"map": "s1"}, moves=done.moves, after=2)
    assert settled.moves is done.moves  # nothing to write


@pytest.mark.parametrize(("robot_state", "online"), [(None, True), (state(), False)])
def test_nothing_without_a_state_or_for_a_robot_offline(robot_state: State | None, online: bool) -> None:
    moves = ZoneSetMoves({"s1": Move.SEND}, NOW - RESEND * 10)

    result = plan(robot_state, {"map": "s1"}, moves=moves, online=online)

    assert (moves_of(result), result.moves) == ([], moves)
