"""Scaling out: two bridges in one MQTT shared-subscription group and a second step worker.

Which bridge sees a robot's state, and which process runs its step, must not matter: the Redis script
keeps only a robot's newer states and every step holds the robot's row lock. So each robot's orders must
come exactly as with one bridge and one worker, while both bridges take part.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from itertools import groupby, pairwise
from typing import Any

import pytest

from fleet.celery import app
from tests.e2e.conftest import BRIDGE, WORKER, Process, Recorder, Stack
from tests.e2e.helpers import action, composite, create_robot, post_mission, route, wait_mission
from tests.faults.checks import carried_leaf
from tests.waiting import wait_for
from vda5050.orders import order_id

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

ROBOTS = 4
MISSIONS = 3  # per robot, queued at once


def mission_tree(leg: float) -> list[dict[str, Any]]:
    """Four leaves: routes and an action, two of them inside a sequence; the last route goes ahead."""
    return [
        route("out", (leg, 0), (leg, 1)),
        composite("work", "sequence"),
        action("load", should_fail=0, time=0.1, parent="work"),
        route("carry", (0, 1), parent="work"),
        route("home", (0, 0)),
    ]


LEAVES = [index for index, node in enumerate(mission_tree(1)) if "route" in node or "action" in node]


@pytest.fixture
def scaled_out(stack: Stack) -> Iterator[tuple[list[Process], str]]:
    """Two bridges sharing the robots' messages instead of the harness's one, and a second step worker;
    yields the bridges and the worker's node name once all three are ready. The harness's own bridge is
    back afterwards."""
    group = f"e2e-{uuid.uuid4().hex[:8]}"  # the broker is shared with other test runs
    single = stack.processes["bridge"]
    single.stop()
    bridges = [stack.add(f"bridge-{group}-{i}", [*BRIDGE, "--share-group", group]) for i in (1, 2)]
    node = f"{group}@scale-out"
    worker = stack.add(f"worker-{group}", [*WORKER, "-n", node])
    try:
        wait_for(
            lambda: all(f"$share/{group}/" in bridge.output() for bridge in bridges),
            message="both bridges subscribed in the group",
        )
        wait_for(lambda: app.control.ping([node], timeout=0.5), message="the second worker ready")
        yield bridges, node
    finally:
        for process in (*bridges, worker):
            stack.processes.pop(process.name).stop()
        single.start()


def assert_orders_in_order(recorder: Recorder, robot: str, missions: list[str]) -> None:
    """Leaves in tree order, missions in submission order, each order sent before the next one starts
    (a resend repeats the latest order, never an earlier one); orderUpdateId and headerId never go back. A
    route sent ahead counts as its leaf's order (`carried_leaf`)."""
    orders = recorder.for_robot(robot, "order")
    expected = [order_id(mission, leaf, 0) for mission in missions for leaf in LEAVES]
    assert [leaf for leaf, _ in groupby(carried_leaf(o) for o in orders)] == expected
    updates = [(expected.index(carried_leaf(o)), o["orderUpdateId"]) for o in orders]
    assert updates == sorted(updates)
    header_ids = [o["headerId"] for o in orders]
    assert header_ids == sorted(set(header_ids)), "headerIds must increase"


def test_two_bridges_and_two_workers_keep_each_robots_orders_in_order(
    api, unique, recorder, simulator, scaled_out
):
    robots = [unique(f"scale{i}") for i in range(ROBOTS)]
    simulator(*(f"{robot},0,0" for robot in robots))
    for robot in robots:
        create_robot(api, robot)
    missions = {robot: [f"{robot}-m{k}" for k in range(MISSIONS)] for robot in robots}
    for robot, names in missions.items():
        for k, name in enumerate(names):
            post_mission(api, name, robot, mission_tree(leg=1 + k))
    for robot, names in missions.items():
        statuses = [wait_mission(api, name)["status"] for name in names]
        assert [status["state"] for status in statuses] == ["COMPLETED"] * MISSIONS, statuses
        for earlier, later in pairwise(statuses):
            assert later["start_timestamp"] >= earlier["end_timestamp"]  # FIFO, one at a time
        assert_orders_in_order(recorder, robot, names)
    bridges, node = scaled_out
    for bridge in bridges:
        assert bridge.running(), f"{bridge.name} exited:\n{bridge.output()[-4000:]}"
    # Both workers took steps: Celery's own statistics, as `celery -A fleet inspect stats` shows them.
    stats = app.control.inspect(timeout=2).stats()
    steps_run = {name: worker["total"].get("fleet.step_robots", 0) for name, worker in stats.items()}
    assert steps_run[node] > 0, steps_run
    assert sum(count > 0 for count in steps_run.values()) >= 2, steps_run
