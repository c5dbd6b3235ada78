"""Wire messages of test robots, as the bridge receives them: (topic, payload) pairs."""

from datetime import UTC, datetime, timedelta
from typing import Any

from missions.robot_step import robot_step
from missions.services import mission_create
from robots import livestate
from robots.models import Robot
from tests.dispatch.builders import robot_state
from tests.factories import TEST_ACTOR
from vda5050.codec import encode, header_for
from vda5050.models import (
    AgvPosition,
    ConnectionContent,
    ConnectionState,
    Content,
    FactsheetContent,
    OrderContent,
    VisualizationContent,
)
from vda5050.topics import RobotAddress
from workers import step_requests
from workers.bridge.loop import Bridge

T0 = datetime(2026, 3, 1, 12, 0, 0, tzinfo=UTC)


def address(robot: Robot | str, version: str = "2.0.0") -> RobotAddress:
    name = robot if isinstance(robot, str) else robot.serial_number
    return RobotAddress("uagv", "RobotCompany", name, version)


def topic(robot: Robot | str, kind: str) -> str:
    name = robot if isinstance(robot, str) else robot.serial_number
    return f"uagv/v2/RobotCompany/{name}/{kind}"


def wire(
    robot: Robot | str, content: Content, *, header_id: int = 1, at: float = 0.0, version: str = "2.0.0"
) -> bytes:
    """`content` as `robot` sends it (speaking `version`), stamped `at` seconds after T0."""
    header = header_for(address(robot, version), header_id=header_id, at=T0 + timedelta(seconds=at))
    return encode(content, header)


def state_message(
    robot: Robot | str, *, header_id: int = 1, at: float = 0.0, **fields: Any
) -> tuple[str, bytes]:
    """A (topic, payload) state of `robot`; `fields` as for tests.dispatch.builders.robot_state."""
    return topic(robot, "state"), wire(robot, robot_state(**fields), header_id=header_id, at=at)


def connection_message(
    robot: Robot | str, connection_state: ConnectionState, *, header_id: int = 1, at: float = 0.0
) -> tuple[str, bytes]:
    content = ConnectionContent(connection_state=connection_state)
    return topic(robot, "connection"), wire(robot, content, header_id=header_id, at=at)


def visualization_message(
    robot: Robot | str, x: float, y: float, theta: float, *, at: float = 0.0
) -> tuple[str, bytes]:
    position = AgvPosition(x=x, y=y, theta=theta, map_id="map", position_initialized=True)
    content = VisualizationContent(agv_position=position)
    return topic(robot, "visualization"), wire(robot, content, at=at)


def factsheet_message(robot: Robot | str, factsheet: FactsheetContent) -> tuple[str, bytes]:
    return topic(robot, "factsheet"), wire(robot, factsheet)


def step_requested(robot: Robot | str) -> bool:
    """Whether a step was queued for the robot since the last check (its marker), which clears it; the
    steps requested in the background (`step_requests.queue_steps_soon`) are queued first."""
    step_requests.wait_until_queued(timeout=10)
    name = robot if isinstance(robot, str) else robot.name
    return bool(livestate.client().delete(livestate.step_marker_key(name)))


def steps_queued(robots: list[Robot]) -> set[str]:
    """Those of `robots` whose step is queued (the markers stay)."""
    markers = livestate.client().mget([livestate.step_marker_key(robot.name) for robot in robots])
    return {robot.name for robot, marker in zip(robots, markers, strict=True) if marker is not None}


def running_order(bridge: Bridge, robot: Robot) -> str:
    """Bring the robot online idle, give it a mission and run the step that sends its order; the orderId."""
    bridge.handle([state_message(robot, header_id=1, at=0.0)])
    step_requested(robot)
    route = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}
    mission_create(
        actor=TEST_ACTOR,
        name=f"{robot.name}-m",
        prefix=None,
        spec={"robot": robot.name, "mission_tree": [route]},
    )
    orders = [m.content for m in robot_step(name=robot.name).messages if isinstance(m.content, OrderContent)]
    assert len(orders) == 1
    return orders[0].order_id
