"""Zone access end to end (issue 46) for 2.x robots: real API, bridge, workers, beat, Mosquitto and simulated
robots, which know nothing of zones; the dispatcher alone keeps them apart by holding their orders' bases
back at a RELEASE zone's edge. Checked from every state the robots send: never two inside a zone at once.
"""

import re
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

import orjson
import pytest
from rest_framework.test import APIClient

from dispatch.step import ZONE_WAITING
from tests.e2e.conftest import Recorder, Simulator
from tests.e2e.helpers import Tap, create_robot, get, post_mission, route, tapped, wait_mission, wait_robot
from tests.waiting import wait_for
from tests.zones import bodies
from vda5050.polygons import Point, contains

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# Slow enough, and reporting often enough, that each robot's states show it inside a 2 m zone a few times.
MOTION = ("--speed", "4", "--state_period", "0.1")


def square(x: float, y: float, size: float = 2.0) -> tuple[Point, ...]:
    return ((x, y), (x + size, y), (x + size, y + size), (x, y + size))


def zone_set(api: APIClient, name: str, zones: dict[str, tuple[Point, ...]]) -> None:
    """A zone set of map `map` with these RELEASE zones (capacity 1), enabled."""
    body = bodies.zone_set(
        name,
        zones=[
            bodies.zone("RELEASE", zone_id, vertices=[{"x": x, "y": y} for x, y in vertices])
            for zone_id, vertices in zones.items()
        ],
    )
    assert api.post("/zone_set", body, format="json").status_code == 200
    assert api.post(f"/zone_set/{name}/enable").status_code == 200


def robots_at(api, simulator, unique, *places: tuple[str, float, float], **spec: Any) -> dict[str, Simulator]:
    """Simulated robots created through the API, online, by name: each its own simulator (to kill)."""
    robots = {(name := unique(base)): simulator(f"{name},{x},{y}", extra=MOTION) for base, x, y in places}
    for name in robots:
        create_robot(api, name, **spec)
    for name in robots:
        wait_robot(api, name, online=True)
    return robots


def run_to_completion(api: APIClient, unique, routes: dict[str, list[tuple[float, float]]]) -> None:
    """A mission per robot through its route's points, posted together; each completes."""
    missions = [
        post_mission(api, unique(f"m-{robot}"), robot, [route("r", *points)])
        for robot, points in routes.items()
    ]
    for mission in missions:
        assert wait_mission(api, mission["name"])["status"]["state"] == "COMPLETED"


@contextmanager
def taps(*robots: str) -> Iterator[dict[str, Tap]]:
    with ExitStack() as stack:
        yield {robot: stack.enter_context(tapped(robot)) for robot in robots}


def poses(tap: Tap) -> list[tuple[datetime, Point]]:
    """Each state's time (the robot's clock: one machine) and position (3.0: mobileRobotPosition)."""
    return [
        (datetime.fromisoformat(state["timestamp"]), (position["x"], position["y"]))
        for state in tap.of("state")
        if (position := state.get("agvPosition") or state.get("mobileRobotPosition"))
    ]


def inside_together(recorded: dict[str, Tap], zone: tuple[Point, ...]) -> tuple[list[str], set[str]]:
    """Replay every robot's states in time order: the moments two robots' last reported poses were both in
    `zone`, and the robots seen in it at all."""
    events = sorted((at, robot, point) for robot, tap in recorded.items() for at, point in poses(tap))
    last: dict[str, Point] = {}
    together: list[str] = []
    seen: set[str] = set()
    for at, robot, point in events:
        last[robot] = point
        inside = sorted(name for name, where in last.items() if contains(zone, where))
        seen.update(inside)
        if len(inside) > 1:
            together.append(f"{at.isoformat()}: {inside}")
    return together, seen


def test_two_robots_crossing_one_zone_are_never_inside_it_together_and_both_complete(api, simulator, unique):
    aisle = square(0, 0)
    zone_set(api, unique("crossing"), {"aisle": aisle})
    east, south = robots_at(api, simulator, unique, ("east", -2, 1), ("south", 1, 4))

    with taps(east, south) as recorded:
        run_to_completion(api, unique, {east: [(4, 1)], south: [(1, -2)]})

    together, seen = inside_together(recorded, aisle)
    assert together == []
    assert seen == {east, south}  # the check saw both cross


def test_two_robots_crossing_two_zones_in_opposite_orders_both_complete(api, simulator, unique):
    west_zone, east_zone = square(0, 0), square(4, 0)
    zone_set(api, unique("two"), {"west": west_zone, "east": east_zone})
    eastward, westward = robots_at(api, simulator, unique, ("eastward", -2, 0.5), ("westward", 8, 1.5))

    with taps(eastward, westward) as recorded:
        # Each stops between the zones (at x = 3, outside both) and needs next the zone the other leaves.
        run_to_completion(api, unique, {eastward: [(3, 0.5), (8, 0.5)], westward: [(3, 1.5), (-2, 1.5)]})

    for zone in (west_zone, east_zone):
        together, seen = inside_together(recorded, zone)
        assert together == []
        assert seen == {eastward, westward}


def test_a_robot_killed_inside_a_zone_frees_it_after_its_heartbeat_timeout(api, simulator, unique):
    zone_set(api, unique("dead"), {"aisle": square(0, 0)})
    [(stuck, stuck_simulator)] = robots_at(
        api, simulator, unique, ("stuck", -2, 1), heartbeat_timeout=2.0
    ).items()
    (passing,) = robots_at(api, simulator, unique, ("passing", 1, 4))
    into = unique("m-into")
    post_mission(api, into, stuck, [route("into", (1, 1))])  # a route ending inside holds the zone
    assert wait_mission(api, into)["status"]["state"] == "COMPLETED"
    held = wait_robot(
        api, stuck, zone_access={"held": [{"map_id": "map", "zone_id": "aisle"}], "waiting": []}
    )
    assert held["status"]["online"]

    through = unique("m-through")
    post_mission(api, through, passing, [route("across", (1, -2))])
    wait_for(
        lambda: (get(api, "mission", through)["status"]["waiting_reason"] or "").startswith(ZONE_WAITING),
        message="the passing robot waiting for the zone",
    )
    stuck_simulator.process.kill()

    assert wait_mission(api, through)["status"]["state"] == "COMPLETED"
    assert get(api, "robot", stuck)["status"]["online"] is False
    # The plan lets the zone go on its next run after the robot left it, a moment after the mission ended.
    wait_robot(api, passing, zone_access={"held": [], "waiting": []})


# Where robots crossing the square at (0, 0) start and where they go: from the west, north, east and south.
CROSSINGS = [((-2, 1), (4, 1)), ((1, 4), (1, -2)), ((4, 0.5), (-2, 0.5)), ((1.5, -2), (1.5, 4))]


@pytest.mark.parametrize(
    "versions",
    [("2.0.0", "3.0.0"), ("3.0.0", "3.0.0"), ("2.0.0", "3.0.0", "2.0.0", "3.0.0")],
    ids=["2.x-3.0", "3.0-3.0", "two-of-each"],
)
def test_2_x_and_3_0_robots_crossing_one_zone_share_its_grants_and_all_complete(
    api, simulator, unique, recorder: Recorder, versions: tuple[str, ...]
):
    """A 3.0 robot holds the zone set (its factsheet lists RELEASE), asks for the zone at its edge and is
    answered on the responses topic; a 2.x robot is held back by its order: one set of grants."""
    aisle = square(0, 0)
    robots = {unique(f"cross{index}v{version[0]}"): version for index, version in enumerate(versions)}
    for (name, version), ((x, y), _) in zip(robots.items(), CROSSINGS, strict=False):
        simulator(f"{name},{x},{y},0,map,0,50,RobotCompany,{name},CARRIER,{version}", extra=MOTION)
        create_robot(api, name, vda5050={"version": version})
    speaking_3_0 = [name for name, version in robots.items() if version == "3.0.0"]
    for name in speaking_3_0:
        wait_for(
            lambda name=name: (
                get(api, "robot", name)["status"]["factsheet"]["supported_zones"] == ["RELEASE"]
            ),
            message="the 3.0 robot's factsheet",
        )
    zone_set_name = unique("mixed")
    zone_set(api, zone_set_name, {"aisle": aisle})
    enabled = [{"map_id": "map", "zone_set_id": zone_set_name, "zone_set_status": "ENABLED"}]
    for name in speaking_3_0:
        wait_for(
            lambda name=name: get(api, "robot", name)["status"]["zone_sets"] == enabled,
            message="zone set on the robot",
        )

    with taps(*robots) as recorded:
        run_to_completion(api, unique, {name: [to] for name, (_, to) in zip(robots, CROSSINGS, strict=False)})

    together, seen = inside_together(recorded, aisle)
    assert together == []
    assert seen == set(robots)
    for name in speaking_3_0:  # each 3.0 robot asked, and was let through on the responses topic
        asked = [r for state in recorded[name].of("state") for r in state.get("zoneRequests") or []]
        assert {r["zoneId"] for r in asked} == {"aisle"}
        answers = [a for message in recorder.for_robot(name, "responses") for a in message["responses"]]
        assert {a["requestId"] for a in answers if a["grantType"] == "GRANTED"} == {
            r["requestId"] for r in asked
        }


def readme_bodies(section: str) -> list[dict[str, Any]]:
    """The JSON bodies of the curl commands in the README's section `section` (up to the next heading)."""
    text = (Path(__file__).resolve().parents[2] / "README.md").read_text().split(f"### {section}\n", 1)[1]
    return [orjson.loads(body) for body in re.findall(r"-d '([^']*)'", text.split("\n### ", 1)[0])]


def test_the_readmes_two_robots_take_turns_through_its_aisle(api, simulator, unique):
    """README, "Zone access": `make run`'s two robots where they start, "Zone sets"' set, the two missions."""
    zone_set_body = readme_bodies("Zone sets")[0]
    assert api.post("/zone_set", zone_set_body, format="json").status_code == 200
    assert api.post(f"/zone_set/{zone_set_body['name']}/enable").status_code == 200
    carter01, carter02 = robots_at(api, simulator, unique, ("carter01", 4, 5), ("carter02", 9, 9))
    names = {"carter01": carter01, "carter02": carter02}
    missions = [{**body, "robot": names[body["robot"]]} for body in readme_bodies("Zone access")]
    assert [mission["robot"] for mission in missions] == [carter01, carter02]

    with taps(carter01, carter02) as recorded:
        for mission in missions:
            assert api.post("/mission", mission, format="json").status_code == 200
        for mission in missions:
            assert wait_mission(api, mission["name"])["status"]["state"] == "COMPLETED"

    aisle = tuple((v["x"], v["y"]) for v in zone_set_body["zones"][0]["vertices"])
    together, seen = inside_together(recorded, aisle)
    assert together == []
    assert seen == {carter01, carter02}
