"""Robots that take an order update but never execute it (issue #43): after FLEET_ORDER_STALL_SECONDS
without progress the order is canceled, the rest goes out as a new order, and the robot gets the
compatibility rule `order_update_not_executed`, so later missions send it no route ahead. Against the
simulator's mimic of the PyPI vda5050-sdk 0.2.0 vehicle, and that vehicle itself (its own AGV client,
unmodified, in an environment of its own)."""

import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from django.conf import settings

from tests.e2e.conftest import Process, Recorder, Simulator, Stack, running
from tests.e2e.helpers import create_robot, get, post_mission, route, wait_mission
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

STALL_SECONDS = "3"
TIMEOUT = 300  # the missions': they must end well before
PATIENCE = 60  # how long the test waits for one to end
RULE = "order_update_not_executed"
SDK_PACKAGES = ["vda5050-sdk[mqtt]==0.2.0", "aiomqtt==2.5.1", "paho-mqtt==2.2.0"]


@pytest.fixture(scope="module")
def quick_stall(stack: Stack) -> Iterator[None]:
    """The stack's worker and beat with FLEET_ORDER_STALL_SECONDS=3 while this module runs."""
    with stack.reconfigured("worker", "beat", FLEET_ORDER_STALL_SECONDS=STALL_SECONDS):
        yield


def rules(api, robot: str) -> list[str]:
    return [rule["rule"] for rule in get(api, "robot", robot)["vda5050"]["compatibility_rules"]]


def at(api, robot: str) -> tuple[int, int]:
    pose = get(api, "robot", robot)["status"]["pose"]
    return round(pose["x"]), round(pose["y"])


def cancels(recorder: Recorder, robot: str) -> int:
    return sum(
        action["actionType"] == "cancelOrder"
        for message in recorder.for_robot(robot, "instantActions")
        for action in message.get("actions", [])
    )


def two_route_missions(api, recorder: Recorder, unique, robot: str, *, stalls: bool) -> None:
    """A two-route mission completes: through the stall check, recording the rule (`stalls`), or directly
    on the route sent ahead; a second one then completes with no route sent ahead (after the rule) and
    nothing canceled."""
    first = unique("ahead")
    post_mission(api, first, robot, [route("a", (3, 0)), route("b", (3, 3))], timeout=TIMEOUT)
    status = wait_mission(api, first, timeout=PATIENCE)["status"]
    assert status["state"] == "COMPLETED", status
    assert (RULE in rules(api, robot), cancels(recorder, robot) >= 1) == (stalls, stalls)
    assert any(order["orderUpdateId"] == 1 for order in recorder.for_robot(robot, "order"))
    wait_for(lambda: at(api, robot) == (3, 3), message="the robot at the second route's end")

    sent_before, canceled_before = len(recorder.for_robot(robot, "order")), cancels(recorder, robot)
    second = unique("after")
    post_mission(api, second, robot, [route("c", (0, 3)), route("d", (0, 0))], timeout=TIMEOUT)
    status = wait_mission(api, second, timeout=PATIENCE)["status"]
    assert status["state"] == "COMPLETED", status
    orders = recorder.for_robot(robot, "order")[sent_before:]
    ahead = any(order["orderUpdateId"] > 0 for order in orders)
    assert ahead != stalls and len({order["orderId"] for order in orders}) == (1 if ahead else 2)
    assert cancels(recorder, robot) == canceled_before


def test_a_simulated_robot_that_takes_updates_but_never_executes_them_completes_its_missions(
    api, simulator: Callable[..., Simulator], unique, recorder: Recorder, quick_stall: None
) -> None:
    robot = unique("sdkmimic")
    simulator(f"{robot},0,0,0,map,0,80,,,,,vda5050-sdk-0.2", extra=("--speed", "2"))
    create_robot(api, robot)

    two_route_missions(api, recorder, unique, robot, stalls=True)


SDK_ENV = (
    Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mission-dispatch" / "vda5050-sdk-0.2.0"
)


@pytest.fixture(scope="module")
def vda5050_sdk() -> Path:
    """The Python of an environment with PyPI vda5050-sdk 0.2.0 (made once, kept in the user's cache);
    the test is skipped where it cannot be installed. Not beside our own pins: its top-level package is
    named `vda5050`, as ours is."""
    python = SDK_ENV / "bin" / "python"
    if not python.exists():
        made = subprocess.run([sys.executable, "-m", "venv", str(SDK_ENV)], capture_output=True, timeout=120)
        if made.returncode != 0:
            pytest.skip(
                f"no virtual environment for vda5050-sdk: {made.stderr.decode(errors='replace')[-300:]}"
            )
    installed = subprocess.run(
        [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *SDK_PACKAGES],
        capture_output=True,
        timeout=300,
    )
    if installed.returncode != 0:
        pytest.skip(
            f"pip could not install {SDK_PACKAGES}: {installed.stderr.decode(errors='replace')[-300:]}"
        )
    return python


@contextmanager
def vda5050_sdk_agv(
    robot: str, executors: str, stack: Stack, python: Path, tmp_path: Path
) -> Iterator[Process]:
    """The real vda5050-sdk 0.2.0 vehicle as robot `robot` (interface uagv, which the library fixes) on the
    test broker, while the block runs; `executors` as `pypi/vda5050_sdk_agv.py` takes them."""
    with running(
        Process(
            "vda5050-sdk",
            [
                str(python),
                str(Path(__file__).with_name("pypi") / "vda5050_sdk_agv.py"),
                f"mqtt://{settings.MQTT_HOST}:{settings.MQTT_PORT}",
                "RobotCompany",
                robot,
                "2.1.0",
                "0",
                "0",
                "1.0",  # seconds from node to node
                executors,
            ],
            {key: value for key, value in stack.env.items() if key != "PYTHONPATH"},
            tmp_path / "agv.log",
        )
    ) as agv:
        yield agv


@pytest.mark.parametrize(("executors", "stalls"), [("one", True), ("per-order", False)])
def test_the_real_vda5050_sdk_0_2_vehicle_completes_two_route_missions(
    api,
    unique,
    stack: Stack,
    recorder: Recorder,
    vda5050_sdk: Path,
    tmp_path: Path,
    quick_stall: None,
    executors: str,
    stalls: bool,
) -> None:
    """Its vehicle with one executor stalls on the route sent ahead (issue #43) and gets the rule; with an
    executor per order, as the library's FakeAgv, it drives the update."""
    robot = unique("sdkagv")
    with vda5050_sdk_agv(robot, executors, stack, vda5050_sdk, tmp_path):
        create_robot(api, robot, vda5050={"interface_name": "uagv"})

        two_route_missions(api, recorder, unique, robot, stalls=stalls)
