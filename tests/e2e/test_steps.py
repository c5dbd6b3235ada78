"""Every dispatch step runs on the Celery step workers: dispatch stops with them and resumes with them, and
a step worker killed in the middle of many missions loses none of them."""

from __future__ import annotations

import time

import pytest

from tests.e2e.helpers import create_robot, get, order_contents, post_mission, route, wait_mission, wait_robot

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# How long nothing may happen while no step worker runs (it would take well under a second otherwise).
WITHOUT_WORKERS_SECONDS = 3.0


def test_dispatch_stops_while_no_step_worker_runs_and_resumes_when_one_starts(
    api, simulator, unique, stack, recorder
):
    robot = unique("idle")
    simulator(f"{robot},0,0")
    create_robot(api, robot)
    wait_robot(api, robot, online=True)
    worker = stack.processes["worker"]
    worker.stop()
    try:
        name = post_mission(api, unique("m"), robot, [route("r", (1, 0))])["name"]
        time.sleep(WITHOUT_WORKERS_SECONDS)

        assert get(api, "mission", name)["status"]["state"] == "PENDING"
        assert recorder.for_robot(robot, "order") == []
    finally:
        worker.start()
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"


def test_a_step_worker_killed_amid_many_missions_loses_none_and_sends_no_order_twice_differently(
    api, simulator, unique, stack, recorder
):
    robots = [unique(f"many{i}") for i in range(4)]
    simulator(*(f"{robot},0,0" for robot in robots), extra=("--speed", "4"))
    missions = []
    for robot in robots:
        create_robot(api, robot)
        for k in range(3):
            legs = [route(f"leg{i}", (1 + k, i), (0, i)) for i in range(2)]
            missions.append(post_mission(api, unique(f"{robot}-m{k}"), robot, legs)["name"])
    assert wait_mission(api, missions[0])["status"]["state"] == "COMPLETED"  # well under way

    stack.processes["worker"].restart()  # SIGKILL, then start again

    assert [wait_mission(api, name, timeout=120)["status"]["state"] for name in missions] == [
        "COMPLETED"
    ] * len(missions)
    for robot in robots:
        contents = order_contents(recorder.for_robot(robot, "order"))
        assert all(len(bodies) == 1 for bodies in contents.values()), robot
