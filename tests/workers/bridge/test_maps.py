"""Maps through the real path: the bridge coalesces a robot's reported maps into its status flush, a change
of maps asks for a step, and a map action asked through the service goes out with its parameters and is
tracked to its end by the robot's steps (real PostgreSQL and Redis; MQTT bypassed)."""

from collections.abc import Callable
from datetime import timedelta

import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from missions.models import Mission
from missions.services import mission_create
from robots.choices import MapAction
from robots.models import InstantAction, Robot
from robots.services import robot_map_action
from tests.dispatch.builders import robot_state
from tests.factories import TEST_ACTOR
from tests.missions.test_robot_step import instant_actions, put_state, step
from tests.workers.bridge.messages import T0, step_requested
from vda5050.codec import encode, header_for
from vda5050.models import ActionStatus, Map, MapStatus, ZoneSetState
from vda5050.topics import RobotAddress
from workers.bridge.loop import Bridge

MakeRobot = Callable[..., Robot]
HALL = Map(map_id="hall", map_version="2", map_description="hall, 2nd floor", map_status=MapStatus.ENABLED)
YARD = Map(map_id="yard", map_version="1", map_status=MapStatus.DISABLED)


def maps_state(robot: Robot, *maps: Map, header_id: int = 1, action_states=()) -> tuple[str, bytes]:
    """A state of `robot` in its own version, on its own topic, reporting `maps`."""
    version = robot.protocol_version
    content = robot_state(action_states=action_states).model_copy(update={"maps": list(maps)})
    header = header_for(
        RobotAddress("uagv", "RobotCompany", robot.serial_number, version),
        header_id=header_id,
        at=T0 + timedelta(seconds=header_id),
    )
    return f"uagv/v{version[0]}/RobotCompany/{robot.serial_number}/state", encode(content, header)


def flush_statements(bridge: Bridge) -> list[str]:
    with CaptureQueriesContext(connection) as queries:
        bridge.status_writer.flush()
    return [q["sql"] for q in queries if not q["sql"].startswith(("SAVEPOINT", "RELEASE SAVEPOINT"))]


@pytest.mark.parametrize("version", ["2.1.0", "3.0.0"])
def test_reported_maps_reach_the_row_only_on_flush_and_unchanged_maps_are_not_rewritten(
    bridge: Bridge, make_robot: MakeRobot, version: str
) -> None:
    robot = make_robot(vda5050={"version": version})
    bridge.directory.reload()

    bridge.handle([maps_state(robot, HALL, YARD)])
    assert Robot.objects.get(name=robot.name).maps == []

    bridge.status_writer.flush()

    assert Robot.objects.get(name=robot.name).maps == [
        {"map_id": "hall", "map_version": "2", "map_status": "ENABLED", "map_description": "hall, 2nd floor"},
        {"map_id": "yard", "map_version": "1", "map_status": "DISABLED", "map_description": None},
    ]
    bridge.handle([maps_state(robot, HALL, YARD, header_id=2)])
    assert flush_statements(bridge) == []


def test_a_robot_whose_map_changes_gets_a_step(bridge: Bridge, make_robot: MakeRobot) -> None:
    robot = make_robot(vda5050={"version": "2.1.0"})
    bridge.directory.reload()
    bridge.handle([maps_state(robot, YARD)])
    step_requested(robot)

    bridge.handle([maps_state(robot, YARD.model_copy(update={"map_status": MapStatus.ENABLED}), header_id=2)])

    assert step_requested(robot)


def put_maps_state(robot: Robot, *maps: Map, header_id: int, action_states=()) -> None:
    """Store a state reporting `maps` as the bridge does."""
    state = robot_state(action_states=action_states).model_copy(update={"maps": list(maps)})
    put_state(robot, header_id=header_id, state=state)


@pytest.mark.django_db(transaction=True)
def test_a_map_action_is_sent_with_its_parameters_and_its_end_is_stored(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="maps", vda5050={"version": "2.1.0"})
    Robot.objects.filter(name=robot.name).update(online=True)
    InstantAction.objects.filter(robot=robot).update(status=ActionStatus.FINISHED.value)  # factsheet
    put_maps_state(robot, YARD, header_id=1)

    queued = robot_map_action(
        actor=TEST_ACTOR, robot=robot, action=MapAction.ENABLE, map_id="yard", map_version="1"
    )
    [sent] = instant_actions(step(robot))

    assert (sent.action_type, sent.action_id) == ("enableMap", queued.action_id)
    assert {p.key: p.value for p in sent.action_parameters or ()} == {"mapId": "yard", "mapVersion": "1"}
    put_maps_state(
        robot,
        YARD.model_copy(update={"map_status": MapStatus.ENABLED}),
        header_id=2,
        action_states=[(queued.action_id, ActionStatus.FINISHED, "enableMap")],
    )
    step(robot, after=1)
    assert InstantAction.objects.get(action_id=queued.action_id).status == ActionStatus.FINISHED


@pytest.mark.django_db(transaction=True)
def test_a_mission_on_a_map_not_enabled_waits_and_starts_once_it_is(make_robot: MakeRobot) -> None:
    robot = make_robot(prefix="maps", vda5050={"version": "2.1.0"})
    Robot.objects.filter(name=robot.name).update(online=True)
    put_maps_state(robot, YARD, header_id=1)
    waypoint = {"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "yard"}
    mission_create(
        actor=TEST_ACTOR,
        name=f"{robot.name}-m",
        prefix=None,
        spec={"robot": robot.name, "mission_tree": [{"name": "r", "route": {"waypoints": [waypoint]}}]},
    )

    step(robot)
    held = Mission.objects.get(name=f"{robot.name}-m")
    assert (held.state, held.waiting_reason) == ("PENDING", "Waiting for map yard to be enabled on the robot")

    put_maps_state(robot, YARD.model_copy(update={"map_status": MapStatus.ENABLED}), header_id=2)
    step(robot, after=1)
    started = Mission.objects.get(name=f"{robot.name}-m")
    assert (started.state, started.waiting_reason) == ("RUNNING", None)


def test_reported_zone_sets_reach_the_row_on_flush(bridge: Bridge, make_robot: MakeRobot) -> None:
    """3.0 robots report the zone sets they hold (state.zoneSets), coalesced as maps are."""
    robot = make_robot(vda5050={"version": "3.0.0"})
    bridge.directory.reload()
    content = robot_state().model_copy(
        update={
            "zone_sets": [
                ZoneSetState(map_id="hall", zone_set_id="hall-v2", zone_set_status=MapStatus.ENABLED),
                ZoneSetState(map_id="hall", zone_set_id="hall-v1", zone_set_status=MapStatus.DISABLED),
            ]
        }
    )
    header = header_for(
        RobotAddress("uagv", "RobotCompany", robot.serial_number, "3.0.0"), header_id=1, at=T0
    )

    bridge.handle([(f"uagv/v3/RobotCompany/{robot.serial_number}/state", encode(content, header))])
    bridge.status_writer.flush()

    assert Robot.objects.get(name=robot.name).zone_sets == [
        {"map_id": "hall", "zone_set_id": "hall-v2", "zone_set_status": "ENABLED"},
        {"map_id": "hall", "zone_set_id": "hall-v1", "zone_set_status": "DISABLED"},
    ]
