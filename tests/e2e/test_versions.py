"""Mixed fleets: 2.0, 2.1 and 3.0 robots side by side, a 3.0 robot that was created without a version,
and a robot whose stack bends the standard as npm vda-5050-lib 1.4.0 does. Real bridge, worker, beat and
simulator processes; every order and instant action recorded and validated against its version's schema."""

import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from django.conf import settings

from tests.e2e.conftest import Process, running
from tests.e2e.helpers import (
    action,
    create_robot,
    get,
    post_mission,
    route,
    tapped,
    wait_mission,
    wait_mission_where,
    wait_robot,
)
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_a_fleet_of_2_0_2_1_and_3_0_robots_runs_the_same_missions(api, unique, simulator, recorder):
    robots = {version: unique(f"v{version.replace('.', '')}") for version in ("2.0.0", "2.1.0", "3.0.0")}
    simulator(*(f"{name},0,0,0,map,0,80,RobotCompany,{name},CARRIER,{v}" for v, name in robots.items()))
    create_robot(api, robots["2.0.0"], vda5050={"version": "2.0.0"})
    create_robot(api, robots["2.1.0"], vda5050={"version": "2.1.0"})
    create_robot(api, robots["3.0.0"])  # no version: its messages tell
    missions = {}
    for version, robot in robots.items():
        missions[version] = unique(f"m{version.replace('.', '')}")
        tree = [
            route("goto_pickup", (1.5, 1.5), (3.3, 2.1)),
            action("pickup", should_fail=0, time=0.2),
            route("goto_dropoff", (4.0, 3.2), (5.0, 5.0)),
        ]
        post_mission(api, missions[version], robot, tree)

    for version, name in missions.items():
        assert wait_mission(api, name)["status"]["state"] == "COMPLETED", version
    shown = get(api, "robot", robots["3.0.0"])["vda5050"]
    assert (shown["version"], shown["version_source"]) == ("3.0.0", "LEARNED")
    for version, robot in robots.items():
        orders = recorder.for_robot(robot, "order")
        assert {o["version"] for o in orders} == {version}
    orders_3 = recorder.for_robot(robots["3.0.0"], "order")
    assert all("startNodeId" not in edge for order in orders_3 for edge in order["edges"])


def test_teleop_of_a_3_0_robot_whose_instant_actions_report_apart(api, unique, simulator):
    """3.0 reports startTeleop/stopTeleop in instantActionStates: they must still move the robot's state."""
    robot = unique("tele3")
    simulator(f"{robot},0,0,0,map,0,80,RobotCompany,{robot},CARRIER,3.0.0")
    create_robot(api, robot, vda5050={"version": "3.0.0"})
    wait_robot(api, robot, online=True)

    assert api.post(f"/robot/{robot}/teleop?params=START").status_code == 200
    wait_robot(api, robot, state="TELEOP")
    assert api.post(f"/robot/{robot}/teleop?params=STOP").status_code == 200
    wait_robot(api, robot, state="IDLE")


def test_a_vda_5050_lib_1_4_robot_cancels_a_running_mission_with_no_setting_changed(
    api, unique, simulator, recorder
):
    robot = unique("npm")
    simulator(f"{robot},0,0,0,map,0,80,RobotCompany,{robot},CARRIER,2.0.0,vda-5050-lib-1.4")
    create_robot(api, robot)  # instant_actions_key left to its default
    mission = unique("far")
    post_mission(api, mission, robot, [route("far", (60, 0))])
    wait_mission_where(api, mission, lambda status: status["state"] == "RUNNING")

    assert api.post(f"/mission/{mission}/cancel").status_code == 200

    assert wait_mission(api, mission)["status"]["state"] == "CANCELED"
    shown = get(api, "robot", robot)["vda5050"]
    assert (shown["instant_actions_key"], shown["instant_actions_key_source"]) == (
        "instantActions",
        "LEARNED",
    )
    assert [rule["rule"] for rule in shown["compatibility_rules"]] == ["legacy_instant_actions_key"]
    cancels = [
        message
        for message in recorder.for_robot(robot, "instantActions")
        if any(a["actionType"] == "cancelOrder" for a in message.get("instantActions", ()))
    ]
    assert cancels, "the cancelOrder went out under the legacy key"

    # `actions` until the robot's rejection was read (a busy machine may resend before that), then only
    # the legacy key.
    keys = [
        "actions" if "actions" in message else "instantActions"
        for message in recorder.for_robot(robot, "instantActions")
    ]
    switched = keys.index("instantActions")
    assert switched > 0 and set(keys[:switched]) == {"actions"} and set(keys[switched:]) == {"instantActions"}


NPM_PACKAGE = "vda-5050-lib@1.4.0"


@pytest.fixture(scope="module")
def vda5050_lib(tmp_path_factory) -> Path:
    """node_modules with npm vda-5050-lib 1.4.0; the test is skipped without Node or the npm registry."""
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.skip("Node.js is not installed")
    prefix = tmp_path_factory.mktemp("npm")
    install = subprocess.run(
        ["npm", "install", "--no-save", "--no-audit", "--no-fund", "--prefix", str(prefix), NPM_PACKAGE],
        capture_output=True,
        timeout=300,
    )
    if install.returncode != 0:
        pytest.skip(f"npm could not install {NPM_PACKAGE}: {install.stderr.decode(errors='replace')[-300:]}")
    return prefix / "node_modules"


@contextmanager
def vda5050_lib_agv(robot: str, stack, node_modules: Path, tmp_path: Path) -> Iterator[Process]:
    """The real vda-5050-lib 1.4.0 virtual AGV as robot `robot` on the test broker, while the block runs."""
    with running(
        Process(
            "vda-5050-lib",
            [
                "node",
                str(Path(__file__).with_name("npm") / "vda5050_lib_agv.js"),
                f"mqtt://{settings.MQTT_HOST}:{settings.MQTT_PORT}",
                "uagv",
                "RobotCompany",
                robot,
            ],
            {**stack.env, "NODE_PATH": str(node_modules)},
            tmp_path / "agv.log",
        )
    ) as agv:
        yield agv


def test_the_real_vda_5050_lib_1_4_agv_cancels_a_running_mission_with_no_setting_changed(
    api, unique, stack, vda5050_lib, tmp_path
):
    robot = unique("npmagv")
    with vda5050_lib_agv(robot, stack, vda5050_lib, tmp_path):
        create_robot(api, robot, vda5050={"interface_name": "uagv"})  # as the AGV runs
        mission = unique("far")
        post_mission(api, mission, robot, [route("far", (60, 0))])
        wait_mission_where(api, mission, lambda status: status["state"] == "RUNNING")
        wait_for(lambda: get(api, "robot", robot)["status"]["pose"]["x"] > 1, message="the AGV driving")

        assert api.post(f"/mission/{mission}/cancel").status_code == 200

        assert wait_mission(api, mission)["status"]["state"] == "CANCELED"
        shown = get(api, "robot", robot)["vda5050"]
        assert shown["instant_actions_key"] == "instantActions"
        assert "legacy_instant_actions_key" in [rule["rule"] for rule in shown["compatibility_rules"]]


def test_the_real_vda_5050_lib_1_4_agv_takes_the_next_route_as_an_order_update(
    api, unique, stack, vda5050_lib, tmp_path
):
    """Routes without stops against a real stack: it stitches the update at the first route's last node."""
    robot = unique("npmroutes")
    with vda5050_lib_agv(robot, stack, vda5050_lib, tmp_path):
        create_robot(api, robot, vda5050={"interface_name": "uagv"})  # as the AGV runs
        mission = unique("two")
        with tapped(robot) as tap:
            post_mission(api, mission, robot, [route("a", (3, 0)), route("b", (3, 3))])
            status = wait_mission(api, mission)["status"]
            states = tap.of("state")

        assert status["state"] == "COMPLETED", status
        [order_id] = {o["orderId"] for o in tap.of("order")}
        assert any(s["orderId"] == order_id and s["orderUpdateId"] == 1 and s["nodeStates"] for s in states)
        pose = get(api, "robot", robot)["status"]["pose"]
        assert (round(pose["x"]), round(pose["y"])) == (3, 3)
