"""The watch streams against the whole system: missions run by the simulator, seen on GET /mission/watch and
GET /robot/watch transition by transition, across a restart of the bridge and of the step worker."""

import itertools
from typing import Any

import pytest

from tests.e2e.helpers import create_robot, get, post_mission, route, wait_mission
from tests.granian_server import healthy
from tests.waiting import wait_for
from tests.watching import Watch, watches

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
__all__ = ["watches"]

LEAF_STATES = ["PENDING", "RUNNING", "COMPLETED"]


def _distinct(values: list[Any]) -> list[Any]:
    return [value for i, value in enumerate(values) if i == 0 or values[i - 1] != value]


def test_every_transition_of_simulated_missions_reaches_the_watcher(
    api, simulator, unique, stack, api_token, watches
):
    wait_for(lambda: healthy(stack.stream_url), message="the stream process")
    robot = unique("watch")
    simulator(f"{robot},0,0", extra=("--speed", "4"))
    create_robot(api, robot)
    auth = {"Authorization": f"Bearer {api_token}"}
    missions = Watch(f"{stack.stream_url}/mission/watch?robot={robot}", auth)
    robots = Watch(f"{stack.stream_url}/robot/watch?names={robot}", auth)
    watches.extend([missions, robots])
    assert robots.next()["name"] == robot  # the snapshot

    legs = [route(f"leg{i}", point) for i, point in enumerate([(3, 0), (3, 3), (0, 3), (0, 0)])]
    names = [post_mission(api, unique(f"m{i}"), robot, legs)["name"] for i in range(3)]
    wait_for(lambda: get(api, "mission", names[0])["status"]["current_node"] >= 1, message="second leg")
    stack.processes["bridge"].restart()
    wait_for(lambda: get(api, "mission", names[1])["status"]["state"] == "RUNNING", message="second mission")
    stack.processes["worker"].restart()
    finals = {name: wait_mission(api, name, timeout=120) for name in names}
    assert all(final["status"]["state"] == "COMPLETED" for final in finals.values())

    seen: dict[str, list[dict[str, Any]]] = {name: [] for name in names}
    stream: list[tuple[str, str]] = []  # (mission, state), in the stream's order
    while any(not lines or lines[-1] != finals[name] for name, lines in seen.items()):
        line = missions.next()
        seen[line["name"]].append(line)
        stream.append((line["name"], line["status"]["state"]))
    for name, lines in seen.items():
        assert _distinct([line["status"]["state"] for line in lines]) == ["PENDING", "RUNNING", "COMPLETED"]
        for leg in ("leg0", "leg1", "leg2", "leg3"):
            states = _distinct([line["status"]["node_status"][leg]["state"] for line in lines])
            assert states == LEAF_STATES, (name, leg, states)
        assert _distinct([line["status"]["current_node"] for line in lines]) == sorted(
            set(line["status"]["current_node"] for line in lines)
        )
        assert len(lines) == len(_distinct(lines))  # no line twice in a row
    # The missions ran one after another, and the stream shows them in that order.
    for earlier, later in itertools.pairwise(names):
        assert stream.index((earlier, "COMPLETED")) < stream.index((later, "RUNNING"))
    robot_states = []
    while (line := robots.next())["status"]["state"] != "IDLE" or "ON_TASK" not in robot_states:
        robot_states.append(line["status"]["state"])
    assert "ON_TASK" in robot_states
