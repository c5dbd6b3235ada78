"""The live fleet page in Chromium, served as `make run` serves it, without robots that drive: the login it
needs, and a fleet of 1,000 robots whose status changes through the bridge's own writes."""

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from django.conf import settings
from django.db import connection
from django.utils import timezone

from access.choices import command_actor
from missions.rows import RELEASE_SQL, binding_time
from missions.services import mission_create, missions_assign
from robots.models import Robot
from robots.services import robot_create
from robots.status import robot_check_heartbeats, robot_status_write, robots_came_online
from tests.browser import allow_database, chromium_page, log_in, needs_chromium
from tests.fleetpage.page import PASSWORD, fleet_page, page_server, staff_user
from tests.granian_server import GranianServer
from tests.server_env import SERVER_ENV
from tests.waiting import wait_for
from tests.zones.bodies import zone
from zones.services import zone_set_create, zone_set_disable, zone_set_enable

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True), needs_chromium]
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

FLEET = 1000
STATUS_COLUMNS = ("pose_x", "pose_y", "pose_theta", "pose_map_id", "battery_level")


@pytest.fixture
def server(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[GranianServer]:
    allow_database(monkeypatch)
    with page_server(tmp_path, env={**SERVER_ENV, "FLEET_REDIS_URL": settings.REDIS_URL}) as server:
        yield server


def test_the_page_needs_a_staff_users_login(server: GranianServer):
    clerk, operator = staff_user("clerk", staff=False), staff_user("operator")
    with chromium_page() as page:
        page.goto(f"{server.url}/fleet")
        assert page.url == f"{server.url}/admin/login/?next=/fleet"

        log_in(page, f"{server.url}/fleet", username=clerk, password=PASSWORD)
        expect(page.locator(".errornote")).to_contain_text("staff account")
        assert page.url.startswith(f"{server.url}/admin/login/")

        log_in(page, f"{server.url}/fleet", username=operator, password=PASSWORD)
        page.wait_for_url(f"{server.url}/fleet")
        expect(page.locator("#stream")).to_have_attribute("data-stream", "live")


def pose(index: int, step: int) -> tuple[float, float, float]:
    """Robot `index`'s pose at `step`: on a 40 x 25 grid, 2 m apart, each robot `step` moves of its own off
    its place (the first of each row never moves along x)."""
    x = 2.0 * (index % 40) + 0.5 * step * (index % 3)
    y = 2.0 * (index // 40) + 0.25 * step * (index % 5)
    return x, y, (index % 8 - 4) * math.pi / 4


def write_status(names: list[str], step: int) -> None:
    """The bridge's status flush of every robot at once."""
    rows = [
        (*pose(index, step), "hall", float((index + step) % 101), name) for index, name in enumerate(names)
    ]
    assert not robot_status_write(columns=STATUS_COLUMNS, rows=rows)


def expected_titles(names: list[str], step: int, online: bool) -> dict[str, str]:
    titles = {}
    for index, name in enumerate(names):
        x, y, theta = pose(index, step)
        titles[name] = (
            f"{name}: IDLE, {'online' if online else 'offline'}, battery {(index + step) % 101}%, "
            f"at ({x:.2f}, {y:.2f}) heading {round(math.degrees(theta))}°"
        )
    return titles


def assert_drawn_at_poses(centres: dict[str, tuple[float, float]], names: list[str], step: int) -> None:
    """Every marker where its robot's pose is, on one scale for x and y (y up), found from two robots that
    never move along x (indices 0 and 39, the ends of the first row)."""
    (x0, y0, _), (x1, _, _) = pose(0, step), pose(39, step)
    (left, top), (right, _) = centres[names[0]], centres[names[39]]
    scale = (right - left) / (x1 - x0)
    assert scale > 1
    for index, name in enumerate(names):
        x, y, _ = pose(index, step)
        expected = (left + scale * (x - x0), top - scale * (y - y0))
        assert centres[name] == pytest.approx(expected, abs=1.5), name


def test_a_thousand_robots_are_drawn_and_follow_their_status(server: GranianServer):
    names = [f"k{index:04d}" for index in range(FLEET)]
    for name in names:
        robot_create(actor=command_actor("test"), name=name, prefix=None, spec={})
    robots_came_online(names=names)
    write_status(names, 0)

    with fleet_page(server.url, username=staff_user()) as fleet:
        fleet.mark_loaded()
        wait_for(lambda: fleet.titles() == expected_titles(names, 0, True), "1,000 robots at their poses")
        expect(fleet.page.locator("#counts")).to_contain_text(f"{FLEET} robots, {FLEET} online")

        for step in (1, 2):
            write_status(names, step)
            expected = expected_titles(names, step, True)
            wait_for(lambda expected=expected: fleet.titles() == expected, f"the robots' step {step}")
        assert_drawn_at_poses(fleet.centres(), names, 2)

        robot_check_heartbeats()  # nothing heard from them: all offline
        wait_for(lambda: set(fleet.conditions().values()) == {"offline"}, "1,000 robots offline")
        assert fleet.titles() == expected_titles(names, 2, False)
        expect(fleet.page.locator("#counts")).to_contain_text(f"{FLEET} robots, 0 online")
        assert fleet.still_loaded()


def test_a_mission_given_back_to_assignment_leaves_its_robots_queue_on_the_page(
    server: GranianServer, make_robot, settings
):
    settings.ASSIGNMENT_QUIET_SECONDS = 0.0  # bound at once: the burst hold has tests of its own
    robot = make_robot(prefix="giver")
    Robot.objects.filter(name=robot.name).update(
        online=True, battery_level=80.0, last_state_at=timezone.now()
    )
    route = {"route": {"waypoints": [{"x": 1, "y": 0, "map_id": "hall"}]}}
    mission_create(actor=command_actor("test"), name="given", prefix=None, spec={"mission_tree": [route]})
    assert missions_assign().bound == {"given": robot.name}

    with fleet_page(server.url, username=staff_user()) as fleet:
        fleet.select(robot.name)
        queue = fleet.page.locator("#robot-queue li")
        expect(queue).to_have_count(1)
        expect(fleet.mission_row("given").locator(".robot-link")).to_have_text(robot.name)

        # The step's release alone (a step usually writes the mission first, which redraws the robot too).
        now = timezone.now()
        with connection.cursor() as cursor:
            cursor.execute(RELEASE_SQL, [now, binding_time(now), "Robot is offline", "given", robot.name])

        expect(fleet.mission_row("given").locator(".robot-link")).to_have_text("(unbound)")
        expect(queue).to_have_count(0)


def test_the_enabled_zone_sets_of_the_map_shown_are_drawn_with_their_holders_and_follow_enable_and_disable(
    server: GranianServer, make_robot
):
    robot = make_robot(prefix="zoned")
    Robot.objects.filter(name=robot.name).update(
        online=True, pose_map_id="hall", last_state_at=timezone.now()
    )
    actor = command_actor("test")
    spec = {"map_id": "hall", "description": "", "zones": [zone("RELEASE", "aisle"), zone("BLOCKED", "pit")]}
    hall = zone_set_create(actor=actor, name="hall-v1", prefix=None, spec=spec)
    other = zone_set_create(actor=actor, name="yard-v1", prefix=None, spec={**spec, "map_id": "yard"})
    zone_set_enable(actor=actor, zone_set=other)  # another map's: not drawn on this one

    with fleet_page(server.url, username=staff_user()) as fleet:
        fleet.show_map("hall")
        zones = fleet.page.locator("path.zone")
        expect(zones).to_have_count(0)  # the hall's set is not enabled

        zone_set_enable(actor=actor, zone_set=hall)
        expect(zones).to_have_count(2)
        expect(fleet.page.locator('path.zone-release[data-zone="hall-v1/aisle"]')).to_have_count(1)
        expect(fleet.page.locator('path.zone-blocked[data-zone="hall-v1/pit"]')).to_have_count(1)

        # The zone plan grants the robot the aisle (its status.zone_access), then lets it go.
        held = fleet.page.locator('path.zone-held[data-zone="hall-v1/aisle"]')
        expect(held).to_have_count(0)
        access = {"held": [{"map_id": "hall", "zone_id": "aisle"}], "waiting": []}
        Robot.objects.filter(name=robot.name).update(zone_access=access)
        expect(held).to_have_count(1)
        expect(fleet.page.locator("path.zone-held")).to_have_count(1)  # not the pit
        Robot.objects.filter(name=robot.name).update(zone_access={"held": [], "waiting": []})
        expect(held).to_have_count(0)

        zone_set_disable(actor=actor, zone_set=hall)
        expect(zones).to_have_count(0)
