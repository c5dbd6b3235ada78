"""A robot that restarts mid-mission (issue #43): its simulator process is killed (SIGKILL, the test's own
child only) and a fresh one started for the same robot where it stood, which holds no order and numbers
its headerIds from 0 again. The mission does not freeze until its timeout: a route goes on with a new order
of the rest, a running action fails with the reason and the tree's fallback runs."""

from collections.abc import Callable

import pytest

from tests.e2e.conftest import Simulator
from tests.e2e.helpers import (
    action,
    composite,
    create_robot,
    get,
    post_mission,
    route,
    tapped,
    wait_mission,
)
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

TIMEOUT = 300  # the mission's: it must end well before
PATIENCE = 60  # how long the test waits for it to end


def restart_where_it_stands(api, simulator: Callable[..., Simulator], robot: str, running: Simulator) -> None:
    """Kill the robot's simulator and start a fresh one at the pose the robot last reported."""
    running.process.kill()
    pose = get(api, "robot", robot)["status"]["pose"]
    simulator(f"{robot},{pose['x']},{pose['y']},{pose['theta']}", extra=("--speed", "2"))


def test_a_robot_restarted_on_the_first_of_two_routes_completes_the_mission(
    api, simulator, unique, recorder
) -> None:
    robot = unique("restart")
    running = simulator(f"{robot},0,0", extra=("--speed", "2"))
    create_robot(api, robot)
    name = unique("m")
    post_mission(api, name, robot, [route("r1", (4, 0), (8, 0)), route("r2", (8, 4))], timeout=TIMEOUT)

    # under way on the first route, past its first waypoint
    wait_for(
        lambda: get(api, "robot", robot)["status"]["pose"]["x"] > 4.5,
        timeout=PATIENCE,
        message="the robot past the first route's first waypoint",
    )
    restart_where_it_stands(api, simulator, robot, running)

    mission = wait_mission(api, name, timeout=PATIENCE)
    assert mission["status"]["state"] == "COMPLETED", mission["status"]
    order_ids = {order["orderId"] for order in recorder.for_robot(robot, "order")}
    resumed = [order for order in recorder.for_robot(robot, "order") if order["orderId"].endswith("-n0-r1")]
    assert resumed, order_ids  # the first route's rest, as the leaf's next attempt
    assert [(n["nodePosition"]["x"], n["nodePosition"]["y"]) for n in resumed[0]["nodes"][1:]] == [(8, 0)]


def test_a_robot_restarted_during_a_running_action_fails_the_leaf_and_the_fallback_runs(
    api, simulator, unique
) -> None:
    robot = unique("restart")
    running = simulator(f"{robot},0,0", extra=("--speed", "2"))
    create_robot(api, robot)
    name = unique("m")
    tree = [
        composite("s", "selector"),
        action("a", "dummy_action", parent="s", time=60, should_fail=False),
        route("fallback", (1, 1), parent="s"),
    ]
    with tapped(robot) as tap:
        post_mission(api, name, robot, tree, timeout=TIMEOUT)
        wait_for(
            lambda: any(
                a["actionStatus"] == "RUNNING" for state in tap.of("state") for a in state["actionStates"]
            ),
            timeout=PATIENCE,
            message="the action running",
        )

    restart_where_it_stands(api, simulator, robot, running)

    mission = wait_mission(api, name, timeout=PATIENCE)
    assert mission["status"]["state"] == "COMPLETED", mission["status"]
    nodes = mission["status"]["node_status"]
    assert nodes["a"]["state"] == "FAILED"
    assert (
        "no longer holds order" in nodes["a"]["error_msg"]
        and "may or may not have run" in nodes["a"]["error_msg"]
    )
    assert nodes["fallback"]["state"] == "COMPLETED"
