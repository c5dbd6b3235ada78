"""dispatch_mission sends a simulated robot to the point, and the mission completes."""

import math

import pytest
from django.conf import settings

from tests.agents.conftest import text
from tests.e2e.helpers import get, wait_mission, wait_robot
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_dispatch_mission_moves_a_simulated_robot_to_the_point(mcp, api, simulator, unique):
    robot = unique("carter")
    # On the topics of this run's interface (FLEET_VDA5050_INTERFACE_NAME keeps concurrent runs apart).
    simulator(f"{robot},0,0", extra=("--interface_name", settings.VDA5050_INTERFACE_NAME))
    mcp.ok("create_robot", name=robot)
    wait_robot(api, robot, online=True)
    dispatched = mcp.ok("dispatch_mission", robot=robot, x=2.5, y=1.5, theta=0.5)
    name = dispatched.structuredContent["name"]
    assert name.startswith("move_to_2.50_1.50-")
    assert "Target: (2.50, 1.50) @ 0.50 rad" in text(dispatched)
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"

    def arrived() -> bool:
        pose = get(api, "robot", robot)["status"]["pose"]
        return math.isclose(pose["x"], 2.5, abs_tol=0.2) and math.isclose(pose["y"], 1.5, abs_tol=0.2)

    wait_for(arrived, message="the robot at the dispatched point")
    done = mcp.ok("get_mission", name=name)
    assert done.structuredContent["status"]["state"] == "COMPLETED"
    assert "[route]: COMPLETED" in text(done)
