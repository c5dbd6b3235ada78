"""Charging and parking end to end (issue 44): real API, bridge, workers, beat, Mosquitto and simulated
robots whose battery drains while they drive and charges on startCharging. A robot low after a mission
drives to the nearest charger and charges, its next mission waiting until it is charged; two low robots share
one charger in turn; an idle robot parks at the nearest free parking station."""

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from rest_framework.test import APIClient

from dispatch.stations import CHARGING, NO_FREE_CHARGER
from robots.models import InstantAction
from tests.e2e.conftest import Simulator
from tests.e2e.helpers import get, post_mission, route, wait_mission, wait_mission_where, wait_robot
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

DRAIN = 2.0  # percent per metre driven


def post_station(api: APIClient, name: str, x: float, kind: str = "CHARGER") -> None:
    body = {"name": name, "kind": kind, "pose": {"x": x, "y": 0, "theta": 0, "map_id": "map"}}
    response = api.post("/station", body, format="json")
    assert response.status_code == 200, response.content


def robots_with_batteries(
    api,
    simulator,
    unique,
    *robots: tuple[str, float, float],
    battery: dict[str, float] | None = None,
    charge_rate: float | None = None,
    **spec: Any,
) -> Simulator:
    """Simulated robots (base name, x, battery %) draining DRAIN per metre (charging `charge_rate` % per
    second, else the simulator's), created with `battery` and `spec`, online with their factsheet (which
    lists startCharging) stored; their simulator, with their names."""
    names = [unique(base) for base, _, _ in robots]
    rate = "" if charge_rate is None else f",{charge_rate}"
    specs = [
        f"{name},{x},0,0,map,,{level},,,,,,{DRAIN}{rate}"
        for name, (_, x, level) in zip(names, robots, strict=True)
    ]
    started = simulator(*specs)
    for name in names:
        response = api.post("/robot", {"name": name, "battery": battery or {}, **spec}, format="json")
        assert response.status_code == 200, response.content
    for name in names:
        wait_robot(api, name, online=True)
        wait_for(lambda name=name: get(api, "robot", name)["status"]["factsheet"]["speed_max"] > 0)
    return started


def trips(api: APIClient, robot: str, purpose: str) -> list[dict[str, Any]]:
    missions = api.get("/mission", {"robot": robot}).json()
    return [mission for mission in missions if mission["purpose"] == purpose]


def wait_trip(api: APIClient, robot: str, purpose: str = "CHARGE") -> dict[str, Any]:
    return wait_for(
        lambda: (trips(api, robot, purpose) or [None])[-1], message=f"a {purpose} trip of {robot}"
    )


def reservations(api: APIClient, station: str) -> list[str]:
    return get(api, "station", station)["status"]["reservations"]


def test_a_robot_low_after_a_mission_charges_at_the_nearest_charger_and_its_next_mission_waits(
    api, simulator, unique
):
    near, far = unique("near"), unique("far")
    post_station(api, far, 40)
    post_station(api, near, 8)
    battery = {"critical_level": 10, "recommended_minimum": 30, "recommended_maximum": 50}
    (robot,) = robots_with_batteries(api, simulator, unique, ("low", 0, 40), battery=battery).names

    first = unique("first")
    post_mission(api, first, robot, [route("out", (5, 0))])  # 5 m: 40 % to 30 %, its minimum
    assert wait_mission(api, first)["status"]["state"] == "COMPLETED"

    trip = wait_trip(api, robot)
    assert [node["name"] for node in trip["mission_tree"]] == [near, "startCharging"]
    assert reservations(api, near) == [robot]
    second = unique("second")
    post_mission(api, second, robot, [route("back", (0, 0))])
    wait_robot(api, robot, state="CHARGING")
    assert wait_mission(api, trip["name"])["status"]["state"] == "COMPLETED"
    waiting = wait_mission_where(api, second, lambda status: status["waiting_reason"] == CHARGING)
    assert waiting["status"]["state"] == "PENDING"

    done = wait_mission(api, second)
    assert done["status"]["state"] == "COMPLETED"
    charged = get(api, "mission", trip["name"])["status"]["end_timestamp"]
    assert done["status"]["start_timestamp"] > charged
    assert reservations(api, near) == [] and reservations(api, far) == []
    # Charged to 50 % at the charger, 16 % driven back since (uncharged, it would be near 8 %).
    assert get(api, "robot", robot)["status"]["battery_level"] >= 30


def test_two_low_robots_and_one_charger_one_charges_the_other_waits_and_charges_next(api, simulator, unique):
    battery = {"critical_level": 10, "recommended_minimum": 30, "recommended_maximum": 40}
    lower, low = robots_with_batteries(
        api, simulator, unique, ("lower", 0, 24), ("low", 2, 26), battery=battery
    ).names
    charger = unique("charger")
    post_station(api, charger, 5)  # once both can charge (their factsheets in): the lower battery first

    wait_trip(api, lower)
    wait_robot(api, low, charging_waiting_reason=NO_FREE_CHARGER)
    assert reservations(api, charger) == [lower]
    wait_robot(api, lower, state="CHARGING")

    wait_trip(api, low)
    wait_robot(api, low, state="CHARGING")
    assert reservations(api, charger) == [low]
    assert get(api, "robot", lower)["status"]["state"] == "IDLE"
    assert get(api, "robot", lower)["status"]["battery_level"] >= 40
    assert len(trips(api, lower, "CHARGE")) == len(trips(api, low, "CHARGE")) == 1


def test_an_idle_robot_parks_at_the_nearest_free_parking_station(api, simulator, unique, stack):
    near, far = unique("park-near"), unique("park-far")
    post_station(api, far, 12, kind="PARKING")
    post_station(api, near, 3, kind="PARKING")
    with stack.reconfigured("worker", FLEET_PARK_AFTER_SECONDS="2"):
        (robot,) = robots_with_batteries(api, simulator, unique, ("idle", 0, 90)).names

        trip = wait_trip(api, robot, "PARK")
        assert [node["name"] for node in trip["mission_tree"]] == [near]
        assert wait_mission(api, trip["name"])["status"]["state"] == "COMPLETED"
        wait_for(lambda: get(api, "robot", robot)["status"]["pose"]["x"] == 3, message="robot parked")
        assert reservations(api, near) == [robot] and reservations(api, far) == []

        mission = unique("work")
        post_mission(api, mission, robot, [route("away", (6, 0))])
        assert wait_mission(api, mission)["status"]["state"] == "COMPLETED"
        # It left its place with the mission: idle again, it is sent to park anew (a robot holding a
        # station never is).
        wait_for(lambda: len(trips(api, robot, "PARK")) == 2, message="a second parking trip")


def stop_chargings(robot: str) -> int:
    return InstantAction.objects.filter(robot_id=robot, action_type="stopCharging").count()


@contextmanager
def frozen(simulated: Simulator) -> Iterator[None]:
    """The simulator stopped (SIGSTOP: its robots fall silent, their batteries charge on) while the block
    runs, then resumed."""
    simulated.process.send(signal.SIGSTOP)
    try:
        yield
    finally:
        simulated.process.send(signal.SIGCONT)


def test_a_robot_offline_while_charging_takes_its_charger_again_back_online_and_stops_at_its_maximum(
    api, simulator, unique
):
    charger = unique("charger")
    post_station(api, charger, 3)
    battery = {"critical_level": 10, "recommended_minimum": 30, "recommended_maximum": 45}
    away = robots_with_batteries(
        api, simulator, unique, ("away", 0, 20), battery=battery, charge_rate=1.0, heartbeat_timeout=1
    )
    (robot,) = away.names
    trip = wait_trip(api, robot)
    wait_robot(api, robot, state="CHARGING")

    with frozen(away):
        wait_robot(api, robot, online=False)
        wait_for(lambda: reservations(api, charger) == [], message="its charger released")

    wait_robot(api, robot, online=True)
    wait_for(lambda: reservations(api, charger) == [robot], message="its charger taken again")
    assert get(api, "robot", robot)["status"]["state"] == "CHARGING"
    assert [t["name"] for t in trips(api, robot, "CHARGE")] == [trip["name"]]  # no trip to where it is

    charged = wait_robot(api, robot, state="IDLE")["status"]
    assert charged["battery_level"] >= 45 and reservations(api, charger) == []
    assert stop_chargings(robot) == 1


def test_a_robot_back_at_a_charger_another_robot_took_meanwhile_is_told_to_stop(api, simulator, unique):
    charger = unique("charger")
    battery = {"critical_level": 10, "recommended_minimum": 30, "recommended_maximum": 60}
    away = robots_with_batteries(
        api, simulator, unique, ("away", 0, 20), battery=battery, charge_rate=0.5, heartbeat_timeout=1
    )
    (robot,) = away.names
    (other,) = robots_with_batteries(api, simulator, unique, ("other", 6, 25), battery=battery).names
    post_station(api, charger, 3)  # once both can charge: the lower battery first
    wait_robot(api, robot, state="CHARGING")
    wait_robot(api, other, charging_waiting_reason=NO_FREE_CHARGER)

    with frozen(away):
        wait_robot(api, robot, online=False)
        wait_for(lambda: reservations(api, charger) == [other], message="the charger for the other robot")

    wait_robot(api, robot, online=True, state="IDLE")  # told to stop: it charges no more
    assert reservations(api, charger) == [other]
    assert stop_chargings(robot) == 1
