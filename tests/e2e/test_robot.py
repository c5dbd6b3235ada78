"""Reference scenarios `robot.py`, `fail_robot.py`, `retrieve_factsheet.py`, notify nodes."""

import http.server
import signal
import threading
from collections.abc import Iterator
from typing import Any

import orjson
import pytest

from robots.models import Robot
from tests.e2e.helpers import action, create_robot, get, post_mission, route, wait_mission, wait_robot
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_five_robots_run_missions_in_parallel(api, simulator, unique):
    robots = [unique(f"fleet{i}") for i in range(5)]
    simulator(*(f"{name},{i},0" for i, name in enumerate(robots)))
    names = []
    for i, robot in enumerate(robots):
        create_robot(api, robot)
        names.append(post_mission(api, unique(f"m{i}"), robot, [route("r", (i, 2))])["name"])
    assert [wait_mission(api, name)["status"]["state"] for name in names] == ["COMPLETED"] * 5


def test_online_follows_the_robot_and_its_last_will(api, simulator, unique):
    robot = unique("blink")
    create_robot(api, robot, heartbeat_timeout=1)
    assert get(api, "robot", robot)["status"]["online"] is False
    sim = simulator(f"{robot},0,0")
    wait_robot(api, robot, online=True)
    sim.process.kill()  # SIGKILL: the broker publishes the robot's last will
    wait_robot(api, robot, online=False)
    sim = simulator(f"{robot},0,0")
    wait_robot(api, robot, online=True)
    sim.process.stop()  # clean shutdown: OFFLINE
    wait_robot(api, robot, online=False)


def test_heartbeat_timeout_marks_silent_robot_offline(api, simulator, unique):
    robot = unique("quiet")
    create_robot(api, robot, heartbeat_timeout=1)
    sim = simulator(f"{robot},0,0")
    wait_robot(api, robot, online=True)
    sim.process.send(signal.SIGSTOP)  # the connection stays open, but states stop
    try:
        wait_robot(api, robot, online=False)
    finally:
        sim.process.send(signal.SIGCONT)


def test_status_reports_hardware_version_battery_and_pose(api, simulator, unique):
    robot = unique("status")
    simulator(f"{robot},3,4,0,map,0,42,Acme,sn-{robot}")
    create_robot(api, robot, vda5050={"manufacturer": "Acme", "serial_number": f"sn-{robot}"})
    status = wait_robot(api, robot, online=True, battery_level=42)["status"]
    assert status["hardware_version"] == {"manufacturer": "Acme", "serial_number": f"sn-{robot}"}
    assert status["pose"]["x"] == 3 and status["pose"]["y"] == 4 and status["pose"]["map_id"] == "map"
    assert status["position_initialized"] is True


@pytest.mark.parametrize("robot_type", ["MANIPULATOR", "CARRIER"])
def test_factsheet_is_requested_and_stored(api, simulator, unique, robot_type):
    robot = unique("fs")
    simulator(f"{robot},0,0,0,map,0,50,RobotCompany,{robot},{robot_type}")
    create_robot(api, robot)
    wait_for(lambda: Robot.objects.filter(name=robot, factsheet__isnull=False).exists(), message="factsheet")
    status = get(api, "robot", robot)["status"]
    assert status["factsheet"]["agv_class"] == robot_type
    assert status["factsheet"]["speed_max"] == (0 if robot_type == "MANIPULATOR" else 10)
    listed = api.get("/robot", {"robot_type": robot_type, "names": robot}).json()
    assert [r["name"] for r in listed] == [robot]


def test_warning_errors_do_not_fail_but_fatal_errors_do(api, simulator, unique):
    warned, fatal = unique("warn"), unique("fatal")
    simulator(f"{warned},0,0,0,map,1", extra=("--fail_as_warning",))
    simulator(f"{fatal},0,0,0,map,1")
    create_robot(api, warned)
    create_robot(api, fatal)
    ok = post_mission(api, unique("ok"), warned, [route("r", (1, 0))])["name"]
    bad = post_mission(api, unique("bad"), fatal, [route("r", (1, 0))])["name"]
    assert wait_mission(api, ok)["status"]["state"] == "COMPLETED"
    failed = wait_mission(api, bad)["status"]
    assert failed["state"] == "FAILED"
    assert failed["failure_reason"] == "Failure period reached"


def test_teleop_via_api_start_and_stop(api, unique, recorder, simulated_robot):
    robot = simulated_robot("tele")
    wait_robot(api, robot, online=True)
    response = api.post(f"/robot/{robot}/teleop?params=START")
    assert response.status_code == 200 and response.json() == "START teleop action received."
    wait_robot(api, robot, state="TELEOP")
    assert api.post(f"/robot/{robot}/teleop?params=STOP").status_code == 200
    wait_robot(api, robot, state="IDLE")
    types = [a["actionType"] for m in recorder.for_robot(robot, "instantActions") for a in m["actions"]]
    assert "startTeleop" in types and "stopTeleop" in types


def test_teleop_via_pause_order_action(api, unique, simulated_robot):
    robot = simulated_robot("tele")
    name = unique("m")
    post_mission(
        api, name, robot, [route("go", (1, 0)), action("hold", "pause_order"), route("back", (0, 0))]
    )
    wait_robot(api, robot, state="TELEOP")
    assert get(api, "mission", name)["status"]["node_status"]["hold"]["state"] == "RUNNING"
    assert api.post(f"/robot/{robot}/teleop?params=STOP").status_code == 200
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    wait_robot(api, robot, state="IDLE")


class NotifyServer:
    """A local HTTP endpoint answering with scripted statuses and recording what it received."""

    def __init__(self) -> None:
        self.statuses: list[int] = []
        self.received: list[Any] = []
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                body = self.rfile.read(int(self.headers["Content-Length"] or 0))
                server.received.append(orjson.loads(body))
                status = server.statuses.pop(0) if server.statuses else 200
                self.send_response(status)
                self.end_headers()

            def log_message(self, *args: Any) -> None:
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/hook"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()


@pytest.fixture
def notify_server() -> Iterator[NotifyServer]:
    server = NotifyServer()
    yield server
    server.httpd.shutdown()


def notify(name: str, url: str, payload: Any) -> dict[str, Any]:
    return {"name": name, "notify": {"url": url, "json_data": payload, "timeout": 5}}


def test_notify_followed_by_route_continues(api, unique, notify_server, simulated_robot):
    robot = simulated_robot("notify")
    name = unique("m")
    tree = [route("a", (1, 0)), notify("tell", notify_server.url, {"robot": robot}), route("b", (0, 1))]
    status = wait_mission(api, post_mission(api, name, robot, tree)["name"])["status"]
    assert status["state"] == "COMPLETED"
    assert status["node_status"]["tell"]["state"] == "COMPLETED"
    assert status["node_status"]["b"]["state"] == "COMPLETED"
    assert notify_server.received == [{"robot": robot}]


def test_notify_retries_retryable_status_then_succeeds(api, unique, notify_server, simulated_robot):
    robot = simulated_robot("notify")
    notify_server.statuses = [503, 500]
    name = unique("m")
    status = wait_mission(
        api, post_mission(api, name, robot, [notify("tell", notify_server.url, {"n": 1})])["name"]
    )
    assert status["status"]["state"] == "COMPLETED"
    assert len(notify_server.received) == 3


def test_notify_with_non_retryable_status_fails_mission(api, unique, notify_server, simulated_robot):
    robot = simulated_robot("notify")
    notify_server.statuses = [400]
    name = unique("m")
    status = wait_mission(
        api, post_mission(api, name, robot, [notify("tell", notify_server.url, {})])["name"]
    )
    assert status["status"]["state"] == "FAILED"
    assert "400" in status["status"]["node_status"]["tell"]["error_msg"]
    assert len(notify_server.received) == 1
