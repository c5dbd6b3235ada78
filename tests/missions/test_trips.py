"""`missions.trips.stations_plan_run`: charging and parking trips in PostgreSQL (issue 44). Real PostgreSQL,
outside a test transaction, as the workers run; the robots' rows are written as the bridge writes them."""

import threading
import time
from datetime import timedelta
from typing import Any

import pytest
from django.db import connection
from django.test import override_settings
from django.utils import timezone

from dispatch.stations import CHARGING, NO_FREE_CHARGER, NO_START_CHARGING, RETRY_LATER, Resume
from dispatch.vocabulary import MissionPurpose, RobotState, StationKind
from missions.choices import MissionState
from missions.models import Mission
from missions.robot_step import robot_step
from missions.selectors import assignment_inputs
from missions.services import mission_create
from missions.trips import TRIP_PRIORITY, stations_plan_run
from robots.models import InstantAction, Robot
from robots.services import robot_delete
from robots.status import robot_check_heartbeats, robots_came_online
from stations.models import Station
from tests.factories import CAN_CHARGE, TEST_ACTOR, RobotFactory, StationFactory
from tests.missions.test_robot_step import put_state
from vda5050.models import ActionStatus, ActionType

pytestmark = pytest.mark.django_db(transaction=True)


def robot(name: str, *, x: float = 0.0, level: float = 80.0, **fields: Any) -> Robot:
    """An online idle robot at (x, 0) on "map" that can charge, its minimum 30 %, its maximum 90 %."""
    values = dict(
        online=True,
        battery_level=level,
        battery_recommended_minimum=30.0,
        battery_recommended_maximum=90.0,
        pose_x=x,
        pose_map_id="map",
        last_state_at=timezone.now(),
        factsheet=CAN_CHARGE,
    )
    return RobotFactory(name=name, **{**values, **fields})


def station(name: str, *, x: float = 0.0, kind: StationKind = StationKind.CHARGER, **fields: Any) -> Station:
    return StationFactory(name=name, kind=kind, pose_x=x, pose_map_id="map", **fields)


def reservations(name: str) -> list[str]:
    return Station.objects.get(name=name).reservations


def trips(robot_name: str, purpose: MissionPurpose = MissionPurpose.CHARGE) -> list[Mission]:
    return list(Mission.objects.filter(robot=robot_name, purpose=purpose).order_by("queue_position"))


def end_trip(mission: Mission, state: MissionState) -> None:
    Mission.objects.filter(name=mission.name).update(state=state, end_timestamp=timezone.now())


def test_a_low_robot_gets_the_nearest_charger_reserved_and_a_trip_there_ahead_of_its_queue() -> None:
    robot("r1", x=0.0, level=25.0)
    station("far", x=20.0)
    station("near", x=5.0, pose_theta=1.5)

    plan = stations_plan_run()

    assert plan is not None and [trip.station for trip in plan.charging_trips] == ["near"]
    assert reservations("near") == ["r1"] and reservations("far") == []
    [trip] = trips("r1")
    assert (trip.state, trip.priority) == (MissionState.PENDING, TRIP_PRIORITY)
    route, action = trip.mission_tree
    assert route["name"] == "near"
    [waypoint] = route["route"]["waypoints"]
    assert (waypoint["x"], waypoint["y"], waypoint["theta"], waypoint["map_id"]) == (5.0, 0.0, 1.5, "map")
    assert action["action"] == {"action_type": "startCharging", "action_parameters": {}}

    stations_plan_run()  # again: it holds the charger, nothing new
    assert len(trips("r1")) == 1 and reservations("near") == ["r1"]


def test_a_robot_whose_factsheet_lists_no_start_charging_is_never_sent() -> None:
    robot("r1", level=5.0, factsheet=None)
    station("c1")

    plan = stations_plan_run()

    assert plan is not None and plan.waiting == {"r1": NO_START_CHARGING}
    assert trips("r1") == [] and reservations("c1") == []


def test_at_its_maximum_a_charging_robot_is_sent_stop_charging_and_its_charger_freed() -> None:
    robot("r1", level=20.0)
    station("c1")
    stations_plan_run()
    [trip] = trips("r1")
    end_trip(trip, MissionState.COMPLETED)
    Robot.objects.filter(name="r1").update(state=RobotState.CHARGING, battery_level=60.0)

    stations_plan_run()
    assert reservations("c1") == ["r1"]
    assert not InstantAction.objects.filter(robot_id="r1", action_type=ActionType.STOP_CHARGING).exists()

    Robot.objects.filter(name="r1").update(battery_level=90.0)
    plan = stations_plan_run()

    assert plan is not None and plan.stop_charging == ("r1",)
    assert reservations("c1") == []
    assert InstantAction.objects.filter(robot_id="r1", action_type=ActionType.STOP_CHARGING).count() == 1


def test_two_low_robots_and_one_charger_the_lower_charges_first_the_other_next() -> None:
    robot("low", level=12.0, x=9.0)
    robot("lower", level=11.0, x=10.0)
    station("c1")

    plan = stations_plan_run()

    assert plan is not None and plan.waiting == {"low": NO_FREE_CHARGER}
    assert reservations("c1") == ["lower"]
    end_trip(trips("lower")[0], MissionState.COMPLETED)
    Robot.objects.filter(name="lower").update(battery_level=95.0)
    stations_plan_run()  # lower stops; its charger goes to the other at the next run
    stations_plan_run()
    assert reservations("c1") == ["low"]


def test_a_failed_trip_frees_the_charger_and_is_retried_after_a_backoff_not_at_once() -> None:
    robot("r1", level=20.0)
    station("c1")
    stations_plan_run()
    end_trip(trips("r1")[0], MissionState.FAILED)

    plan = stations_plan_run()

    assert plan is not None and reservations("c1") == []
    assert plan.waiting == {"r1": RETRY_LATER} and len(trips("r1")) == 1
    Mission.objects.filter(purpose=MissionPurpose.CHARGE).update(
        end_timestamp=timezone.now() - timedelta(hours=1)
    )
    stations_plan_run()
    assert reservations("c1") == ["r1"] and len(trips("r1")) == 2


def test_an_offline_or_deleted_robot_loses_its_reservation_and_its_trip_is_canceled() -> None:
    robot("gone", level=20.0, x=1.0)
    robot("away", level=20.0, x=2.0)
    station("c1", capacity=2)
    stations_plan_run()
    assert sorted(reservations("c1")) == ["away", "gone"]

    Robot.objects.filter(name="away").update(online=False)
    robot_delete(actor=TEST_ACTOR, robot=Robot.objects.get(name="gone"))
    stations_plan_run()

    assert reservations("c1") == []
    [trip] = trips("away")
    assert trip.state == MissionState.CANCELED


def charging_at_its_charger(name: str, *, level: float, trip_state: MissionState) -> Mission:
    """`name` sent to charge at c1 (at its pose), its trip in `trip_state`, the robot reporting CHARGING."""
    stations_plan_run()
    [trip] = trips(name)
    Mission.objects.filter(name=trip.name).update(state=trip_state, start_timestamp=timezone.now())
    if trip_state == MissionState.COMPLETED:
        end_trip(trip, trip_state)
    Robot.objects.filter(name=name).update(state=RobotState.CHARGING, battery_level=level)
    return trip


def stop_chargings(name: str) -> int:
    return InstantAction.objects.filter(robot_id=name, action_type=ActionType.STOP_CHARGING).count()


@pytest.mark.parametrize(
    "trip_state",
    [MissionState.COMPLETED, MissionState.RUNNING],
    ids=["charging_when_it_went_away", "its_trip_running_when_it_went_away"],
)
def test_a_robot_offline_while_charging_loses_its_charger_and_back_still_charging_takes_it_again(
    trip_state: MissionState,
) -> None:
    robot("r1", level=20.0)
    station("c1")
    trip = charging_at_its_charger("r1", level=25.0, trip_state=trip_state)

    assert robot_check_heartbeats(now=time.time()) == ["r1"]  # never heard within its heartbeat timeout
    stations_plan_run()

    assert reservations("c1") == [] and stop_chargings("r1") == 0
    trip.refresh_from_db()
    if trip_state == MissionState.RUNNING:  # canceled: the engine ends it once the robot is back
        assert trip.needs_canceled
        end_trip(trip, MissionState.CANCELED)
    else:
        assert trip.state == MissionState.COMPLETED

    robots_came_online(names=["r1"])
    plan = stations_plan_run()

    assert plan is not None and plan.resumed == (Resume("r1", "c1"),)
    assert reservations("c1") == ["r1"] and len(trips("r1")) == 1  # no trip to where it stands
    assert plan.waiting == {"r1": CHARGING} and stop_chargings("r1") == 0
    stations_plan_run()  # it keeps it (a trip canceled while it was away is no failed trip)
    assert reservations("c1") == ["r1"]

    Robot.objects.filter(name="r1").update(battery_level=90.0)
    plan = stations_plan_run()
    assert plan is not None and plan.stop_charging == ("r1",) and reservations("c1") == []
    stations_plan_run()  # still charging until it has stopped: neither taken back nor told twice
    assert reservations("c1") == [] and stop_chargings("r1") == 1


def test_a_robot_back_at_a_charger_another_robot_took_meanwhile_is_sent_stop_charging_once() -> None:
    robot("r1", level=20.0)
    station("c1")
    charging_at_its_charger("r1", level=25.0, trip_state=MissionState.COMPLETED)
    robot("other", level=20.0, x=5.0)
    assert stations_plan_run().waiting == {"r1": CHARGING, "other": NO_FREE_CHARGER}

    Robot.objects.filter(name="r1").update(online=False)
    stations_plan_run()
    assert reservations("c1") == ["other"]

    Robot.objects.filter(name="r1").update(online=True)
    plan = stations_plan_run()

    assert plan is not None and plan.stop_charging == ("r1",) and plan.resumed == ()
    assert reservations("c1") == ["other"] and stop_chargings("r1") == 1
    assert Robot.objects.get(name="r1").charging_waiting_reason == NO_FREE_CHARGER
    stations_plan_run()
    assert stop_chargings("r1") == 1 and reservations("c1") == ["other"]


def test_a_charging_robot_is_not_free_for_unbound_missions() -> None:
    robot("r1", state=RobotState.CHARGING)
    route = {"route": {"waypoints": [{"x": 1.0, "y": 0.0, "map_id": "map"}]}}
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec={"mission_tree": [route]})

    [candidate] = assignment_inputs(free_only=False).robots

    assert not candidate.idle
    assert assignment_inputs(free_only=True).robots == []


@override_settings(DISPATCH_PARK_AFTER_SECONDS=60.0)
def test_an_idle_robot_parks_at_the_nearest_free_parking_and_leaves_when_it_gets_a_mission() -> None:
    robot("r1", x=0.0)
    Robot.objects.filter(name="r1").update(created_at=timezone.now() - timedelta(minutes=5))
    robot("new", x=0.0)  # idle for less than a minute
    station("p-far", x=9.0, kind=StationKind.PARKING)
    station("p-near", x=3.0, kind=StationKind.PARKING)

    stations_plan_run()

    assert reservations("p-near") == ["r1"] and reservations("p-far") == []
    [trip] = trips("r1", MissionPurpose.PARK)
    assert [node["name"] for node in trip.mission_tree] == ["p-near"]
    assert trips("new", MissionPurpose.PARK) == []
    end_trip(trip, MissionState.COMPLETED)
    stations_plan_run()
    assert reservations("p-near") == ["r1"]  # parked: it keeps its place

    route = {"route": {"waypoints": [{"x": 1.0, "y": 0.0, "map_id": "map"}]}}
    mission = mission_create(
        actor=TEST_ACTOR, name="m1", prefix=None, spec={"robot": "r1", "mission_tree": [route]}
    )
    Mission.objects.filter(name=mission.name).update(state=MissionState.RUNNING)
    stations_plan_run()
    assert reservations("p-near") == []


def test_many_runs_at_once_never_put_a_station_over_its_capacity() -> None:
    for index in range(10):
        robot(f"r{index:02d}", x=float(index), level=15.0 + index)
    station("c1", x=0.0)
    station("c2", x=9.0, capacity=2)
    barrier = threading.Barrier(5)
    errors: list[BaseException] = []

    def run() -> None:
        try:
            barrier.wait()
            for _ in range(3):
                stations_plan_run()
        except BaseException as error:  # reported below
            errors.append(error)
        finally:
            connection.close()

    threads = [threading.Thread(target=run) for _ in range(5)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    assert not errors
    assert len(reservations("c1")) == 1 and len(reservations("c2")) == 2
    sent = Mission.objects.filter(purpose=MissionPurpose.CHARGE)
    assert sent.count() == 3  # one trip per reservation, never two for a robot
    assert sorted(sent.values_list("robot", flat=True)) == sorted(reservations("c1") + reservations("c2"))
    # The lowest batteries first.
    assert sorted(sent.values_list("robot", flat=True)) == ["r00", "r01", "r02"]


def test_an_operators_request_sends_a_charged_robot_and_ends_once_it_holds_the_charger() -> None:
    robot("busy-charger", level=20.0)
    robot("asked", level=80.0, charge_requested=True)
    station("c1")

    stations_plan_run()  # the request goes first, whatever the batteries

    assert reservations("c1") == ["asked"]
    asked, low = Robot.objects.get(name="asked"), Robot.objects.get(name="busy-charger")
    assert (asked.charge_requested, asked.charging_waiting_reason) == (False, None)
    assert low.charging_waiting_reason == NO_FREE_CHARGER
    assert len(trips("asked")) == 1

    end_trip(trips("asked")[0], MissionState.COMPLETED)
    Robot.objects.filter(name="asked").update(state=RobotState.CHARGING, battery_level=95.0)
    stations_plan_run()  # charged: stopCharging, and no new trip for the request (it ended)
    stations_plan_run()
    assert reservations("c1") == ["busy-charger"] and len(trips("asked")) == 1
    assert Robot.objects.get(name="busy-charger").charging_waiting_reason == CHARGING  # on its way


def test_a_robot_below_its_critical_level_starts_its_charging_trip(make_robot) -> None:
    created = make_robot(prefix="critical")
    Robot.objects.filter(name=created.name).update(
        online=True, battery_level=5.0, pose_map_id="map", last_state_at=timezone.now(), factsheet=CAN_CHARGE
    )
    put_state(created, header_id=1, battery=5.0)  # below the critical level 10, as the step sees it
    station("c1")
    stations_plan_run()
    [trip] = trips(created.name)

    robot_step(name=created.name)

    assert Mission.objects.get(name=trip.name).state == MissionState.RUNNING


@pytest.mark.parametrize(
    ("charger", "free"),
    [
        ({}, False),  # a charger it may use: it charges first
        ({"robot_types": ["FORKLIFT"]}, True),  # only a charger for other robots: it works on
        ({"pose_map_id": "hall"}, True),  # only a charger on another map
        (None, True),  # no charger at all
    ],
    ids=["usable_charger", "charger_for_others", "charger_elsewhere", "no_charger"],
)
def test_a_robot_due_to_charge_is_not_free_for_unbound_missions_while_a_charger_waits_for_it(
    charger: dict[str, Any] | None, free: bool
) -> None:
    robot("low", level=25.0)  # at or below its minimum (30 %), above its critical level
    if charger is not None:
        StationFactory(name="c1", kind=StationKind.CHARGER, **{"pose_map_id": "map", **charger})
    route = {"route": {"waypoints": [{"x": 1.0, "y": 0.0, "map_id": "map"}]}}
    mission_create(actor=TEST_ACTOR, name="m1", prefix=None, spec={"mission_tree": [route]})

    [candidate] = assignment_inputs(free_only=False).robots
    assert candidate.battery_ok is free
    assert [r.name for r in assignment_inputs(free_only=True).robots] == (["low"] if free else [])


@pytest.mark.parametrize("with_charger", [True, False], ids=["charger", "no_charger"])
def test_a_robot_due_to_charge_starts_no_mission_of_its_own_while_a_charger_waits_for_it(
    make_robot, with_charger: bool
) -> None:
    created = make_robot(prefix="due")
    Robot.objects.filter(name=created.name).update(
        online=True,
        battery_level=25.0,
        battery_recommended_minimum=30.0,
        pose_map_id="map",
        last_state_at=timezone.now(),
        factsheet=CAN_CHARGE,
    )
    if with_charger:
        station("c1")
    put_state(created, header_id=1, battery=25.0)
    route = {"route": {"waypoints": [{"x": 1.0, "y": 0.0, "map_id": "map"}]}}
    spec = {"robot": created.name, "mission_tree": [route]}
    mission_create(actor=TEST_ACTOR, name="own", prefix=None, spec=spec)

    robot_step(name=created.name)

    mission = Mission.objects.get(name="own")
    if with_charger:  # it waits for its trip, which the station plan sends next
        assert mission.state == MissionState.PENDING
        assert mission.waiting_reason == "Battery 25% is due to charge (at or below 30%): it charges first"
    else:
        assert mission.state == MissionState.RUNNING


def test_a_stop_charging_refused_before_its_latest_trip_does_not_keep_a_robot_from_its_charger() -> None:
    """Refused once, on an earlier charge: its latest charge is taken up again after an offline spell."""
    robot("r1", level=20.0)
    station("c1")
    InstantAction.objects.create(
        action_id="old-stop", robot_id="r1", action_type=ActionType.STOP_CHARGING, status=ActionStatus.FAILED
    )
    charging_at_its_charger("r1", level=25.0, trip_state=MissionState.COMPLETED)

    Robot.objects.filter(name="r1").update(online=False)
    stations_plan_run()
    assert reservations("c1") == []
    Robot.objects.filter(name="r1").update(online=True)
    stations_plan_run()

    assert reservations("c1") == ["r1"] and len(trips("r1")) == 1  # taken again, not a trip to where it is
    assert stop_chargings("r1") == 1  # the old one alone
