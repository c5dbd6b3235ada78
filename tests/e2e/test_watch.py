"""The streams against the whole system: missions run by the simulator, seen on GET /mission/watch, GET
/robot/watch and GET /events transition by transition, across a restart of the bridge and of the step
worker; the events' client also loses its connection and resumes after its last event, as EventSource does."""

import itertools
import queue
import time
from typing import Any

import pytest

from tests.e2e.helpers import create_robot, get, post_mission, route, wait_mission
from tests.granian_server import healthy
from tests.waiting import wait_for
from tests.watching import Events, Watch, watches

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]
__all__ = ["watches"]

LEAF_STATES = ["PENDING", "RUNNING", "COMPLETED"]


def _distinct(values: list[Any]) -> list[Any]:
    return [value for i, value in enumerate(values) if i == 0 or values[i - 1] != value]


def _read_for_now(events: Events, seconds: float = 2.0) -> list[Any]:
    """What the client reads in the next `seconds` (its connection is then lost), or until a pause."""
    blocks, deadline = [], time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            blocks.append(events.next(timeout=0.3))
        except queue.Empty:
            break
    return blocks


def _by_mission(blocks: list[Any], names: list[str]) -> dict[str, list[dict[str, Any]]]:
    return {name: [block.data for block in blocks if block.data["name"] == name] for name in names}


def test_every_transition_of_simulated_missions_reaches_the_watcher(
    api, simulator, unique, stack, api_token, watches
):
    wait_for(lambda: healthy(stack.api_url), message="the API")
    robot = unique("watch")
    simulator(f"{robot},0,0", extra=("--speed", "4"))
    create_robot(api, robot)
    auth = {"Authorization": f"Bearer {api_token}"}
    missions = Watch(f"{stack.api_url}/mission/watch?robot={robot}", auth)
    robots = Watch(f"{stack.api_url}/robot/watch?names={robot}", auth)
    events_url = f"{stack.api_url}/events?kind=mission&mission.robot={robot}"
    events = Events(events_url, auth)
    watches.extend([missions, robots, events])
    assert robots.next()["name"] == robot  # the snapshot
    snapshot_end = events.next_event()
    assert snapshot_end.event == "snapshot_end"  # no mission yet

    legs = [route(f"leg{i}", point) for i, point in enumerate([(3, 0), (3, 3), (0, 3), (0, 0)])]
    names = [post_mission(api, unique(f"m{i}"), robot, legs)["name"] for i in range(3)]
    wait_for(lambda: get(api, "mission", names[0])["status"]["current_node"] >= 1, message="second leg")
    stack.processes["bridge"].restart()
    had = _read_for_now(events)
    events.close()
    last_id = [block.id for block in [snapshot_end, *had] if block.id is not None][-1]  # as EventSource
    resumed = Events(events_url, {**auth, "Last-Event-ID": last_id})
    watches.append(resumed)
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

    # The events, before and after the resume, are the same changes of each mission, none twice.
    had = [block for block in had if block.event == "mission"]
    while any(not lines or lines[-1] != finals[name] for name, lines in _by_mission(had, names).items()):
        had.append(resumed.next_event())
    assert len({block.id for block in had}) == len(had)
    for name, lines in _by_mission(had, names).items():
        # A resumed stream does not know what the client had: an object's first event may repeat it.
        assert _distinct(lines) == seen[name], name
    robot_states = []
    while (line := robots.next())["status"]["state"] != "IDLE" or "ON_TASK" not in robot_states:
        robot_states.append(line["status"]["state"])
    assert "ON_TASK" in robot_states
