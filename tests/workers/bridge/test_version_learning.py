"""A robot created without a protocol version learns it from what it sends (factsheet, topic, header);
an operator's version is final. Through the real bridge code, PostgreSQL and Redis."""

from datetime import timedelta

import orjson
import pytest

from robots import livestate
from robots.models import Robot
from tests.dispatch.builders import robot_state
from tests.vda5050.samples import full_factsheet
from tests.workers.bridge.messages import T0, step_requested
from vda5050.codec import encode, header_for
from vda5050.models import Content
from vda5050.topics import RobotAddress, Topic, topic_for
from workers.bridge.loop import Bridge

pytestmark = pytest.mark.django_db(transaction=True)  # autocommit, as the bridge runs


def message(robot: Robot, kind: Topic, content: Content, version: str) -> tuple[str, bytes]:
    """`content` on `robot`'s topic of `version`'s major, its header naming `version`."""
    address = RobotAddress(robot.interface_name, robot.manufacturer, robot.serial_number, version)
    header = header_for(address, header_id=1, at=T0 + timedelta(seconds=1))
    return topic_for(address, kind), encode(content, header)


def test_a_3_0_factsheet_makes_an_unversioned_robot_a_3_0_robot(bridge: Bridge, make_robot) -> None:
    robot = make_robot()
    bridge.directory.reload()
    assert (robot.protocol_version, robot.protocol_version_source) == ("2.0.0", "DEFAULT")

    bridge.handle([message(robot, Topic.FACTSHEET, full_factsheet("3.0.0"), "3.0.0")])

    stored = Robot.objects.get(name=robot.name)
    assert (stored.protocol_version, stored.protocol_version_source) == ("3.0.0", "LEARNED")
    assert stored.factsheet["typeSpecification"]["mobileRobotKinematics"] == "DIFFERENTIAL"
    assert stored.speed_max == 1.0
    assert step_requested(robot)  # what waits for the robot goes out again, on v3 topics


def test_a_3_0_state_makes_an_unversioned_robot_a_3_0_robot(bridge: Bridge, make_robot) -> None:
    robot = make_robot()
    bridge.directory.reload()

    bridge.handle([message(robot, Topic.STATE, robot_state(), "3.0.0")])

    assert Robot.objects.get(name=robot.name).protocol_version == "3.0.0"
    assert bridge.directory.versions[robot.name] == ("3.0.0", False)


def test_a_2_1_factsheet_sets_the_minor_version(bridge: Bridge, make_robot) -> None:
    robot = make_robot()
    bridge.directory.reload()

    bridge.handle([message(robot, Topic.FACTSHEET, full_factsheet("2.1.0"), "2.1.0")])

    assert Robot.objects.get(name=robot.name).protocol_version == "2.1.0"


def test_an_operators_version_is_final(bridge: Bridge, make_robot) -> None:
    robot = make_robot(vda5050={"version": "2.0.0"})
    bridge.directory.reload()
    step_requested(robot)

    bridge.handle([message(robot, Topic.STATE, robot_state(), "3.0.0")])  # on v3: not this robot's topic

    stored = Robot.objects.get(name=robot.name)
    assert (stored.protocol_version, stored.protocol_version_source) == ("2.0.0", "OPERATOR")
    assert not step_requested(robot)


def test_a_header_version_of_another_major_than_the_topic_is_not_learned(bridge: Bridge, make_robot) -> None:
    robot = make_robot()
    bridge.directory.reload()
    topic, payload = message(robot, Topic.STATE, robot_state(), "2.0.0")
    body = orjson.loads(payload)
    body["version"] = "3.0.0"

    bridge.handle([(topic, orjson.dumps(body))])

    assert Robot.objects.get(name=robot.name).protocol_version == "2.0.0"


def test_a_message_on_another_majors_topic_naming_no_version_of_it_is_no_robots(
    bridge: Bridge, make_robot
) -> None:
    """An unversioned robot is found on v3 topics, but only by messages that say they are 3.x."""
    robot = make_robot()
    bridge.directory.reload()
    topic, _ = message(robot, Topic.STATE, robot_state(), "3.0.0")
    _, payload_2 = message(robot, Topic.STATE, robot_state(), "2.0.0")

    bridge.handle([(topic, payload_2)])

    assert Robot.objects.get(name=robot.name).protocol_version == "2.0.0"
    assert livestate.latest_state(robot.name).payload is None
