"""The pure station decisions (dispatch.stations): which charger, who waits and why, when to stop charging,
where to park; table-driven cases, then properties over random fleets (bounded and derandomized)."""

from dataclasses import replace
from datetime import UTC, datetime, timedelta

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dispatch.stations import (
    CHARGING,
    GOT_MISSION,
    NO_CHARGER,
    NO_FREE_CHARGER,
    NO_POSE,
    NO_START_CHARGING,
    NOT_IDLE,
    OFFLINE,
    RETRY_LATER,
    TRIP_FAILED,
    Battery,
    Pose,
    StationRobot,
    StationSite,
    Trip,
    plan_stations,
)
from dispatch.vocabulary import StationKind

NOW = datetime(2026, 11, 28, 2, 0, tzinfo=UTC)
CHARGER, PARKING = StationKind.CHARGER, StationKind.PARKING


def robot(name: str, level: float = 80.0, x: float = 0.0, **fields) -> StationRobot:
    battery = fields.pop("battery", {})
    return StationRobot(
        **{
            "name": name,
            "robot_type": "CARRIER",
            "pose": Pose(x, 0.0, "map"),
            "online": True,
            "idle": True,
            "battery": Battery(
                **{
                    "level": level,
                    "critical_level": 10.0,
                    "recommended_minimum": 30.0,
                    "recommended_maximum": 90.0,
                    "charging": False,
                    **battery,
                }
            ),
            "can_charge": True,
            "at_station": False,
            "idle_since": NOW,
            **fields,
        }
    )


def station(name: str, x: float = 0.0, kind: StationKind = CHARGER, **fields) -> StationSite:
    return StationSite(
        **{
            "name": name,
            "kind": kind,
            "pose": Pose(x, 0.0, "map"),
            "robot_types": frozenset(),
            "capacity": 1,
            "reservations": (),
            **fields,
        }
    )


def plan(robots, stations, park_after_seconds=None):
    return plan_stations(robots, stations, now=NOW, park_after_seconds=park_after_seconds)


# --- charging: which charger, who waits ------------------------------------------------------------------

CHARGING_CASES = {
    "a low robot goes to the nearest charger": (
        [robot("r1", 25, x=0)],
        [station("far", x=10), station("near", x=2)],
        {"r1": "near"},
        {},
    ),
    "at its minimum is low, above it is not": (
        [robot("at", 30), robot("above", 30.1)],
        [station("c1"), station("c2")],
        {"at": "c1"},
        {},
    ),
    "no recommended minimum: the critical level decides": (
        [
            robot("r1", 10, battery={"recommended_minimum": None}),
            robot("r2", 11, battery={"recommended_minimum": None}),
        ],
        [station("c1"), station("c2")],
        {"r1": "c1"},
        {},
    ),
    "scarce chargers: the lowest battery first, the others wait": (
        [robot("r1", 20, x=0), robot("r2", 5, x=9), robot("r3", 12, x=0)],
        [station("c1", x=0)],
        {"r2": "c1"},
        {"r1": NO_FREE_CHARGER, "r3": NO_FREE_CHARGER},
    ),
    "a charger of capacity two takes two": (
        [robot("r1", 20), robot("r2", 21), robot("r3", 22)],
        [station("c1", capacity=2)],
        {"r1": "c1", "r2": "c1"},
        {"r3": NO_FREE_CHARGER},
    ),
    "a full charger is not free": (
        [robot("r1", 20), robot("holder", 50)],
        [station("c1", reservations=("holder",)), station("c2", x=30)],
        {"r1": "c2"},
        {},
    ),
    "only chargers of its type and on its map": (
        [robot("r1", 20)],
        [
            station("forklifts", robot_types=frozenset({"FORKLIFT"})),
            station("other-map", pose=Pose(0, 0, "yard")),
            station("carriers", x=50, robot_types=frozenset({"CARRIER", "TUGGER"})),
        ],
        {"r1": "carriers"},
        {},
    ),
    "none it may use": (
        [robot("r1", 20)],
        [station("forklifts", robot_types=frozenset({"FORKLIFT"})), station("p1", kind=PARKING)],
        {},
        {"r1": NO_CHARGER},
    ),
    "a failed trip's backoff not yet over": (
        [robot("r1", 20, retry_at=NOW + timedelta(seconds=1)), robot("r2", 21, retry_at=NOW)],
        [station("c1"), station("c2")],
        {"r2": "c1"},
        {"r1": RETRY_LATER},
    ),
    "an operator's charge now goes first, whatever its battery": (
        [robot("low", 5), robot("asked", 95, charge_now=True)],
        [station("c1")],
        {"asked": "c1"},
        {"low": NO_FREE_CHARGER},
    ),
    "waiting reasons, the first that holds": (
        [
            robot("offline", 20, online=False),
            robot("busy", 20, idle=False),
            robot("no-factsheet", 20, can_charge=False),
            robot("lost", 20, pose=None),
            robot("charging", 20, battery={"charging": True}),
            robot("offline-busy", 20, online=False, idle=False),
        ],
        [station("c1", reservations=("charging",)), station("c2", x=5)],
        {},
        {
            "offline": OFFLINE,
            "busy": NOT_IDLE,
            "no-factsheet": NO_START_CHARGING,
            "lost": NO_POSE,
            "charging": CHARGING,
            "offline-busy": OFFLINE,
        },
    ),
}


@pytest.mark.parametrize(
    ("robots", "stations", "trips", "waiting"), CHARGING_CASES.values(), ids=CHARGING_CASES
)
def test_charging_trips_and_waiting_reasons(robots, stations, trips, waiting):
    result = plan(robots, stations)

    assert {trip.robot: trip.station for trip in result.charging_trips} == trips
    assert result.waiting == waiting
    assert all(trip.kind == CHARGER for trip in result.charging_trips)


def test_a_parked_low_robot_leaves_its_parking_place_for_a_charger():
    result = plan([robot("r1", 20)], [station("p1", kind=PARKING, reservations=("r1",)), station("c1")])

    assert result.charging_trips == (Trip("r1", "c1", CHARGER, leaves="p1"),)
    assert result.reservations == {"c1": ("r1",), "p1": ()}


def test_a_charger_whose_trip_failed_is_released_and_the_next_robot_gets_it():
    result = plan(
        [robot("failed", 20, trip_failed=True, retry_at=NOW + timedelta(seconds=10)), robot("next", 25)],
        [station("c1", reservations=("failed",))],
    )

    assert [(release.robot, release.reason) for release in result.releases] == [("failed", TRIP_FAILED)]
    assert {trip.robot: trip.station for trip in result.charging_trips} == {"next": "c1"}
    assert result.waiting == {"failed": RETRY_LATER}


def test_a_parked_robot_that_ran_a_mission_since_leaves_its_place_even_if_idle_again():
    result = plan([robot("r1", left_parking=True)], [station("p1", kind=PARKING, reservations=("r1",))])

    assert result.reservations == {"p1": ()}
    assert [(release.robot, release.reason) for release in result.releases] == [("r1", GOT_MISSION)]


# --- stopping ----------------------------------------------------------------------------------------------

STOP_CASES = {
    "at its recommended maximum": (robot("r1", 90, at_station=True, battery={"charging": True}), True),
    "below it": (robot("r1", 89, at_station=True, battery={"charging": True}), False),
    "still on its way": (robot("r1", 95, at_station=False), False),
    "no maximum: while charging": (
        robot("r1", 99, at_station=True, battery={"recommended_maximum": None, "charging": True}),
        False,
    ),
    "below it but no longer charging (restarted, unplugged)": (
        robot("r1", 50, at_station=True, battery={"charging": False}),
        True,
    ),
    "no maximum: charging ended": (
        robot("r1", 99, at_station=True, battery={"recommended_maximum": None, "charging": False}),
        True,
    ),
}


@pytest.mark.parametrize(("charging_robot", "stops"), STOP_CASES.values(), ids=STOP_CASES)
def test_stop_charging(charging_robot, stops):
    result = plan([charging_robot], [station("c1", reservations=("r1",))])

    assert result.stop_charging == (("r1",) if stops else ())
    assert result.reservations["c1"] == (() if stops else ("r1",))


def test_a_stopped_charger_is_free_for_the_next_low_robot_in_the_same_plan():
    charged = robot("done", 95, at_station=True)

    result = plan([charged, robot("next", 15)], [station("c1", reservations=("done",))])

    assert result.stop_charging == ("done",)
    assert result.charging_trips == (Trip("next", "c1", CHARGER),)


# --- back at a charger (its reservation released while it was offline) -----------------------------------


def back(name: str, level: float = 50.0, x: float = 0.0, **fields) -> StationRobot:
    """A robot online again, charging at (x, 0), its latest trip ended (at_station) or not."""
    return robot(name, level, x=x, battery={"charging": True}, **fields)


BACK_CASES = {
    "at a free charger: takes it again, no trip": (
        [back("r1", x=0.05)],
        [station("c1")],
        {"c1": ("r1",)},
        (),
    ),
    "its trip canceled while it was away: the same": (
        [back("r1", trip_failed=True, retry_at=NOW + timedelta(seconds=10))],
        [station("c1")],
        {"c1": ("r1",)},
        (),
    ),
    "at a charger another robot took meanwhile: stopCharging": (
        [back("r1"), robot("other", 20, x=9)],
        [station("c1", reservations=("other",))],
        {"c1": ("other",)},
        ("r1",),
    ),
    "two at a charger of one place: the lower battery keeps charging": (
        [back("r1", 60), back("r2", 40)],
        [station("c1")],
        {"c1": ("r2",)},
        ("r1",),
    ),
    "told to stop already: not taken again, not told twice": (
        [back("r1", stopping=True)],
        [station("c1")],
        {"c1": ()},
        (),
    ),
    "charging elsewhere, or at a charger not for it: left alone": (
        [back("r1", x=0.5), back("r2", x=9, robot_type="TUGGER")],
        [station("c1"), station("c9", x=9, robot_types=frozenset({"FORKLIFT"}))],
        {"c1": (), "c9": ()},
        (),
    ),
    "at a parking station: left alone": (
        [back("r1")],
        [station("p1", kind=PARKING)],
        {"p1": ()},
        (),
    ),
}


@pytest.mark.parametrize(("robots", "stations", "reservations", "stops"), BACK_CASES.values(), ids=BACK_CASES)
def test_a_robot_back_at_a_charger_takes_it_again_where_it_has_room_or_stops(
    robots, stations, reservations, stops
):
    result = plan(robots, stations)

    assert result.reservations == reservations
    assert result.stop_charging == stops
    assert result.charging_trips == ()
    assert {(resume.robot, resume.station) for resume in result.resumed} == {
        (name, site.name)
        for site in stations
        for name in reservations[site.name]
        if name not in site.reservations
    }


def test_a_robot_taken_back_stops_at_its_maximum_as_any_other():
    result = plan([back("r1", 95)], [station("c1")])

    assert result.stop_charging == ("r1",)
    assert result.reservations == {"c1": ()}


def test_a_low_robot_stopped_at_a_charger_another_holds_is_sent_to_a_free_one():
    result = plan(
        [back("r1", 20), robot("other", 20, x=9)],
        [station("c1", reservations=("other",)), station("c2", x=30)],
    )

    assert result.stop_charging == ("r1",)
    assert result.charging_trips == (Trip("r1", "c2", CHARGER),)


# --- releases ----------------------------------------------------------------------------------------------


def test_reservations_of_gone_offline_busy_parked_or_doubled_robots_are_released():
    robots = [robot("offline", online=False), robot("busy", idle=False), robot("twice"), robot("stays")]
    stations = [
        station("c1", reservations=("ghost", "offline"), capacity=2),
        station("c2", reservations=("twice", "busy")),  # busy on its way to charge keeps it
        station("p1", kind=PARKING, reservations=("twice",)),
        station("p2", kind=PARKING, reservations=("busy",)),
        station("p3", kind=PARKING, reservations=("stays",)),
    ]

    result = plan(robots, stations)

    assert {(r.robot, r.station) for r in result.releases} == {
        ("ghost", "c1"),
        ("offline", "c1"),
        ("busy", "c2"),  # over capacity (c2 holds one)
        ("twice", "p1"),
        ("busy", "p2"),
    }
    assert result.reservations == {"c1": (), "c2": ("twice",), "p1": (), "p2": (), "p3": ("stays",)}


def test_a_robot_held_by_a_parking_station_and_a_charger_keeps_one_then_goes_to_charge():
    stations = [
        station("a-park", kind=PARKING, reservations=("r2",)),
        station("b-charger", reservations=("r2",)),
    ]

    result = plan([robot("r2", 20)], stations)

    assert {(r.robot, r.station) for r in result.releases} == {("r2", "b-charger"), ("r2", "a-park")}
    assert result.charging_trips == (Trip("r2", "b-charger", CHARGER, leaves="a-park"),)
    assert result.reservations == {"a-park": (), "b-charger": ("r2",)}


# --- parking -----------------------------------------------------------------------------------------------


def idle_for(name: str, seconds: float, **fields) -> StationRobot:
    return robot(name, idle_since=NOW - timedelta(seconds=seconds), **fields)


def test_parking_is_off_unless_asked_for():
    assert plan([idle_for("r1", 3600)], [station("p1", kind=PARKING)]).parking_trips == ()


def test_a_robot_idle_long_enough_parks_at_the_nearest_free_parking_station():
    robots = [
        idle_for("long", 120, x=10),
        idle_for("short", 59),
        idle_for("longer", 300, x=10),
        idle_for("busy", 500, idle=False),
    ]
    stations = [station("p-far", kind=PARKING), station("p-near", kind=PARKING, x=9), station("c1", x=10)]

    result = plan(robots, stations, park_after_seconds=60)

    # The longest idle first: it takes the nearest; the next takes what is left.
    assert result.parking_trips == (Trip("longer", "p-near", PARKING), Trip("long", "p-far", PARKING))


def test_a_robot_at_a_station_or_low_does_not_park():
    robots = [idle_for("parked", 600), idle_for("low", 600, level=20)]
    stations = [station("p1", kind=PARKING, reservations=("parked",)), station("p2", kind=PARKING, x=5)]

    result = plan(robots, stations, park_after_seconds=60)

    assert result.parking_trips == ()
    assert result.waiting == {"low": NO_CHARGER}


# --- properties --------------------------------------------------------------------------------------------

PROPERTIES = settings(max_examples=150, derandomize=True, deadline=None, database=None)
NAMES = [f"r{index}" for index in range(8)]
STATION_NAMES = [f"s{index}" for index in range(5)]
TYPES = ["CARRIER", "FORKLIFT"]
MAPS = ["map", "yard"]


@st.composite
def fleets(draw):
    stations = [
        StationSite(
            name=name,
            kind=draw(st.sampled_from([CHARGER, PARKING])),
            pose=Pose(draw(st.integers(0, 20)), draw(st.integers(0, 20)), draw(st.sampled_from(MAPS))),
            robot_types=frozenset(draw(st.lists(st.sampled_from(TYPES), max_size=1))),
            capacity=draw(st.integers(1, 3)),
            # Whatever the rows hold, even what the rules never make: unknown robots, over capacity, twice.
            reservations=tuple(draw(st.lists(st.sampled_from([*NAMES, "ghost"]), unique=True, max_size=4))),
        )
        for name in draw(st.lists(st.sampled_from(STATION_NAMES), unique=True, max_size=len(STATION_NAMES)))
    ]
    # Anywhere, or at a station (back at a charger, charging, or parked).
    poses = st.none() | st.builds(Pose, st.integers(0, 20), st.integers(0, 20), st.sampled_from(MAPS))
    if stations:
        poses |= st.sampled_from([site.pose for site in stations])
    robots = [
        StationRobot(
            name=name,
            robot_type=draw(st.sampled_from(TYPES)),
            pose=draw(poses),
            online=draw(st.booleans()),
            idle=draw(st.booleans()),
            battery=Battery(
                level=draw(st.integers(0, 100)),
                critical_level=10.0,
                recommended_minimum=draw(st.none() | st.just(30.0)),
                recommended_maximum=draw(st.none() | st.just(90.0)),
                charging=draw(st.booleans()),
            ),
            can_charge=draw(st.booleans()),
            at_station=draw(st.booleans()),
            idle_since=NOW - timedelta(seconds=draw(st.integers(0, 600))),
            stopping=draw(st.booleans()),
        )
        for name in draw(st.lists(st.sampled_from(NAMES), unique=True, max_size=len(NAMES)))
    ]
    return robots, stations, draw(st.none() | st.sampled_from([0, 60, 300]))


@PROPERTIES
@given(fleets())
def test_no_station_over_capacity_and_no_robot_holds_two(fleet):
    robots, stations, park_after = fleet
    result = plan(robots, stations, park_after)

    for site in stations:
        assert len(result.reservations[site.name]) <= site.capacity
    holders = [name for held in result.reservations.values() for name in held]
    assert len(holders) == len(set(holders))
    online = {r.name for r in robots if r.online}
    assert set(holders) <= online


@PROPERTIES
@given(fleets())
def test_releases_then_trips_make_the_new_reservations(fleet):
    robots, stations, park_after = fleet
    result = plan(robots, stations, park_after)
    before = {(name, site.name) for site in stations for name in site.reservations}
    after = {(name, site) for site, held in result.reservations.items() for name in held}
    trips = [*result.charging_trips, *result.parking_trips]

    released = {(release.robot, release.station) for release in result.releases}
    reserved = {(trip.robot, trip.station) for trip in trips}
    resumed = {(resume.robot, resume.station) for resume in result.resumed}

    # Applied in order, releases then resumptions and trips, they make the new reservations (a robot released
    # from a station it held twice may be sent back to it).
    assert released <= before
    assert after == (before - released) | resumed | reserved
    assert not (before - released) & (resumed | reserved)
    assert not resumed & reserved
    assert len({trip.robot for trip in trips}) == len(trips)
    kinds = {site.name: site.kind for site in stations}
    assert all(kinds[trip.station] == trip.kind for trip in trips)


@PROPERTIES
@given(fleets())
def test_every_low_robot_has_a_charger_or_a_reason_and_a_free_charger_leaves_none_waiting_for_one(fleet):
    robots, stations, park_after = fleet
    result = plan(robots, stations, park_after)
    charging = {trip.robot for trip in result.charging_trips}

    for each in robots:
        assert (each.name in charging) + (each.name in result.waiting) == each.battery.low
    # A robot that waits for a free charger waits because every charger it may use is full.
    by_name = {site.name: site for site in stations}
    for name, reason in result.waiting.items():
        if reason == NO_FREE_CHARGER:
            waiting_robot = next(r for r in robots if r.name == name)
            usable = [s for s in stations if s.kind == CHARGER and s.serves(waiting_robot)]
            assert usable and all(
                len(result.reservations[s.name]) == by_name[s.name].capacity for s in usable
            )


@PROPERTIES
@given(fleets())
def test_the_plan_does_not_depend_on_the_order_of_its_inputs(fleet):
    robots, stations, park_after = fleet
    forward = plan(robots, stations, park_after)
    backward = plan(robots[::-1], stations[::-1], park_after)

    assert forward == backward


@PROPERTIES
@given(fleets())
def test_a_second_plan_over_the_first_ones_reservations_sends_no_robot_twice(fleet):
    robots, stations, park_after = fleet
    first = plan(robots, stations, park_after)
    # As the next run reads them: a robot sent on a trip is not at its station (its latest trip is the new).
    sent = {trip.robot for trip in (*first.charging_trips, *first.parking_trips)}
    robots = [replace(r, at_station=False) if r.name in sent else r for r in robots]
    again = plan(robots, [replace(s, reservations=first.reservations[s.name]) for s in stations], park_after)

    assert not again.charging_trips or not (
        {t.robot for t in again.charging_trips} & {t.robot for t in first.charging_trips}
    )
    assert not {t.robot for t in again.parking_trips} & {t.robot for t in first.parking_trips}
