"""A restart of the whole stack with missions running (issue #43): every process `make run` runs (the server
processes of `deploy/Procfile` and a simulator) is stopped as honcho stops them on Ctrl-C (SIGTERM to all,
SIGKILL to any still running 5 s later) and started again. The simulator's robots come back as fresh
processes: no order, headerIds from 0, where a fresh `make run` puts them (their initial poses) or where
they stood. No mission waits for its timeout: each ends within a bound well under it, routes go on with new
orders, an action that was running fails with the reason and its selector's fallback completes the mission.

The package's server processes pause meanwhile (only this test's own processes are ever signalled), so
that no other bridge, worker or beat acts on the test database."""

import signal
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.suite import api_command, worker_command
from tests.e2e.conftest import BRIDGE, CELERY, Process, Stack, simulator_command
from tests.e2e.helpers import (
    action,
    composite,
    create_robot,
    get,
    order_contents,
    post_mission,
    route,
    tapped,
    wait_mission,
)
from tests.granian_server import healthy
from tests.private_redis import free_port
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

TIMEOUT = 120  # the missions': none may end by it
PATIENCE = 60  # how long after the restart every mission must have ended
HONCHO_KILL_WAIT = 5  # s honcho waits after SIGTERM before it SIGKILLs what still runs (honcho.manager)
SPEED = "1"  # m/s: slow enough that the missions are under way when the stack stops


class MakeRun:
    """The processes of `deploy/Procfile` on the test database and Redis: API, bridge, step worker, notify
    worker, beat and a simulator of `robots` (specs `name,x,y,theta`)."""

    def __init__(self, env: dict[str, str], logs: Path, robots: list[str]) -> None:
        self.api_port = free_port()
        node = uuid.uuid4().hex[:6]
        servers = {
            "api": api_command(self.api_port),
            "bridge": BRIDGE,
            "worker": worker_command("steps", f"steps-{node}", 12),
            "notify": worker_command("notify", f"notify-{node}", 8),
            "beat": [CELERY, "-A", "fleet", "beat", "--schedule", str(logs / "beat-schedule")],
        }
        self.processes = [Process(name, argv, env, logs / f"{name}.log") for name, argv in servers.items()]
        self.simulator = Process("simulator", self._simulator(robots), env, logs / "simulator.log")
        self.processes.append(self.simulator)

    @staticmethod
    def _simulator(robots: list[str]) -> list[str]:
        return simulator_command(*robots, extra=("--speed", SPEED))

    def start(self, robots: list[str] | None = None) -> None:
        """Start every process (the simulator's robots at `robots`, if given) and wait for the API."""
        if robots is not None:
            self.simulator.argv = self._simulator(robots)
        for process in self.processes:
            process.start()
        wait_for(
            lambda: healthy(f"http://127.0.0.1:{self.api_port}"), timeout=90, message="the API's /health"
        )

    def stop(self) -> None:
        """As honcho on Ctrl-C: SIGTERM to every process at once, SIGKILL to those still running after
        `HONCHO_KILL_WAIT` seconds."""
        for process in self.processes:
            process.send(signal.SIGTERM)
        deadline = time.monotonic() + HONCHO_KILL_WAIT
        for process in self.processes:
            while process.running() and time.monotonic() < deadline:
                time.sleep(0.1)
            process.kill()


@pytest.fixture
def paused(stack: Stack) -> Iterator[None]:
    """The package's server processes stopped while the test runs, then started again."""
    for process in stack.processes.values():
        process.stop()
    try:
        yield
    finally:
        for process in stack.processes.values():
            process.start()


@pytest.mark.parametrize("where", ["initial poses", "last poses"])
def test_every_mission_ends_after_a_restart_of_the_whole_stack(
    api, stack, paused, unique, recorder, tmp_path, where
) -> None:
    robots = [unique(f"stack{i}") for i in range(3)]
    initial = [f"{robots[0]},0,0,0", f"{robots[1]},0,10,0", f"{robots[2]},0,20,0"]
    run = MakeRun(stack.env, tmp_path, initial)
    run.start()
    try:
        for robot in robots:
            create_robot(api, robot)
        missions = [unique(f"m{i}") for i in range(3)]
        post_mission(
            api, missions[0], robots[0], [route("r1", (4, 0), (8, 0)), route("r2", (8, 4))], timeout=TIMEOUT
        )
        post_mission(
            api,
            missions[1],
            robots[1],
            [route("r1", (4, 10), (8, 10)), route("r2", (8, 14))],
            timeout=TIMEOUT,
        )
        tree = [  # the README's complex mission's shape: an action with a fallback, a route after
            composite("pick", "selector"),
            action("pickup", "dummy_action", parent="pick", time=60, should_fail=0),
            route("pickup_fallback", (1, 20), parent="pick"),
            route("dropoff", (1, 22)),
        ]
        with tapped(robots[2]) as tap:
            post_mission(api, missions[2], robots[2], tree, timeout=TIMEOUT)
            wait_for(
                lambda: any(
                    a["actionStatus"] == "RUNNING" for s in tap.of("state") for a in s["actionStates"]
                ),
                timeout=PATIENCE,
                message="the action running",
            )
        wait_for(
            lambda: all(get(api, "robot", r)["status"]["pose"]["x"] > 4.5 for r in robots[:2]),
            timeout=PATIENCE,
            message="the robots past their first route's first waypoint",
        )
        assert {get(api, "mission", m)["status"]["state"] for m in missions} == {"RUNNING"}

        run.stop()
        poses = [get(api, "robot", r)["status"]["pose"] for r in robots]
        last = [f"{r},{p['x']},{p['y']},{p['theta']}" for r, p in zip(robots, poses, strict=True)]
        restarted = time.monotonic()
        run.start(initial if where == "initial poses" else last)

        ended = {m: wait_mission(api, m, timeout=PATIENCE) for m in missions}
        took = time.monotonic() - restarted
    finally:
        run.stop()
    print(f"every mission ended {took:.1f} s after the restart began")
    assert took < PATIENCE
    for name in missions[:2]:
        assert ended[name]["status"]["state"] == "COMPLETED", ended[name]["status"]
    complex_mission = ended[missions[2]]["status"]
    assert complex_mission["state"] == "COMPLETED", complex_mission
    nodes = complex_mission["node_status"]
    assert nodes["pickup"]["state"] == "FAILED"
    assert "no longer holds order" in nodes["pickup"]["error_msg"]
    assert nodes["pickup_fallback"]["state"] == "COMPLETED"
    for robot in robots:  # no ids sent again with other content, across the restart
        contents = order_contents(recorder.for_robot(robot, "order"))
        assert all(len(bodies) == 1 for bodies in contents.values()), contents
