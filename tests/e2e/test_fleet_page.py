"""The live fleet page in Chromium against the whole system: the API process (granian: the page, its static
files, the REST API, GET /events), the bridge, worker and beat, and simulated robots. What the page shows
comes only from the events; what it does goes through the REST API with the operator's session."""

import math
import re
import time
from collections.abc import Callable, Iterator

import pytest
from django.contrib.sessions.models import Session

from access.choices import WriteAction
from access.models import WriteRecord
from tests.browser import allow_database, needs_chromium
from tests.e2e.conftest import Simulator, Stack
from tests.e2e.helpers import action, composite, create_robot, post_mission, route, wait_mission, wait_robot
from tests.fleetpage.page import FleetPage, fleet_page, staff_user
from tests.granian_server import healthy
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True), needs_chromium]
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


@pytest.fixture
def fleet(stack: Stack, monkeypatch: pytest.MonkeyPatch) -> Iterator[FleetPage]:
    """The page, logged in as a staff user, served by the stack's API process."""
    allow_database(monkeypatch)
    wait_for(lambda: healthy(stack.api_url), "the API process")
    with fleet_page(stack.api_url, username=staff_user()) as page:
        page.mark_loaded()
        yield page
        assert page.still_loaded(), "the page was loaded again"


def at(x: float, y: float) -> str:
    """How a marker's tooltip says where its robot is."""
    return f"at ({x:.2f}, {y:.2f})"


def x_of(title: str) -> float:
    """The x a marker's tooltip gives."""
    return float(re.search(r"at \(([-\d.]+),", title)[1])


def test_robots_are_drawn_at_their_poses_and_move_as_they_drive(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    west, east, hall = unique("west"), unique("east"), unique("hall")
    simulator(f"{west},0,0", f"{east},6,3,{math.pi / 2}", f"{hall},2,2,0,hall", extra=("--speed", "1"))
    create_robot(api, west)
    create_robot(api, east)

    # New robots are on the default map until the bridge writes the poses they report.
    expect(fleet.page.locator("#map-choice option")).to_have_text(["map (2)"])
    expect(fleet.marker(west)).to_have_attribute("title", re.compile(re.escape(at(0, 0))))
    expect(fleet.marker(east)).to_have_attribute("title", re.compile(re.escape(f"{at(6, 3)} heading 90°")))
    create_robot(api, hall)  # now: the page shows the map with the most robots
    expect(fleet.page.locator("#map-choice option")).to_have_text(["hall (1)", "map (2)"])
    # One scale on both axes, y up: east is 6 m right of west and 3 m above it.
    (west_x, west_y), (east_x, east_y) = fleet.centre(west), fleet.centre(east)
    assert east_x - west_x == pytest.approx(2 * (west_y - east_y), rel=0.05)
    assert east_x > west_x
    expect(fleet.marker(hall)).to_have_count(0)  # on another map

    fleet.record(".robot[data-robot]", "title", "data-robot")
    drive = post_mission(api, unique("drive"), west, [route("out", (4, 0))])["name"]
    assert wait_mission(api, drive)["status"]["state"] == "COMPLETED"
    # Where the robot stopped: at its goal, within its deviation.
    wait_for(lambda: abs(x_of(fleet.marker(west).get_attribute("title")) - 4) < 0.1, "the robot at its goal")

    xs = [x_of(title) for title in fleet.recorded()[west]]
    assert any(0.1 < x < 3.9 for x in xs), f"no position on the way: {xs}"
    assert xs == sorted(xs)
    moved_x, moved_y = fleet.centre(west)
    assert moved_x - west_x == pytest.approx((east_x - west_x) * xs[-1] / 6, rel=0.05)
    assert moved_y == pytest.approx(west_y, abs=1)

    fleet.show_map("hall")
    expect(fleet.marker(hall)).to_have_attribute("title", re.compile(re.escape(at(2, 2))))
    expect(fleet.marker(west)).to_have_count(0)


def test_the_running_missions_tree_shows_each_nodes_state_as_it_changes(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    robot = unique("tree")
    simulator(f"{robot},0,0", extra=("--speed", "2"))
    create_robot(api, robot)
    fleet.select(robot)
    fleet.record("#robot-tree li[data-node]", "data-state", "data-node")

    tree = [
        route("out", (3, 0)),
        composite("work", "sequence"),
        action("lift", parent="work", should_fail=0, time=1),
        route("back", (0, 0), parent="work"),
    ]
    name = post_mission(api, unique("m"), robot, tree)["name"]
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"

    expect(fleet.page.locator("#tree-title")).to_have_text(f"Mission {name}: COMPLETED")
    states = fleet.recorded()
    for node in ("out", "work", "lift", "back", "root"):
        assert states[node][-2:] == ["RUNNING", "COMPLETED"], (node, states[node])
    for node in ("lift", "back"):  # not started when the tree was first drawn
        assert states[node] == ["PENDING", "RUNNING", "COMPLETED"], (node, states[node])


def test_the_mission_list_updates_live_and_filters(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    first, second = unique("la"), unique("lb")
    simulator(f"{first},0,0", f"{second},5,0", extra=("--speed", "2"))
    for robot in (first, second):
        create_robot(api, robot)
    fleet.record("#mission-rows tr", "data-state", "data-mission")

    short = post_mission(api, unique("short"), first, [route("go", (3, 0))])["name"]
    expect(fleet.mission_row(short)).to_have_attribute("data-state", "COMPLETED", timeout=60_000)
    assert fleet.recorded()[short][-2:] == ["RUNNING", "COMPLETED"]
    hold = post_mission(api, unique("hold"), second, [action("hold", should_fail=0, time=60)])["name"]
    expect(fleet.mission_row(hold)).to_have_attribute("data-state", "RUNNING")
    assert fleet.listed_missions() == [hold, short]  # started last, listed first

    fleet.filter_missions(state="COMPLETED")
    expect(fleet.page.locator("#mission-rows tr")).to_have_count(1)
    assert fleet.listed_missions() == [short]
    fleet.filter_missions(robot=second)
    expect(fleet.page.locator("#mission-rows tr")).to_have_count(1)
    assert fleet.listed_missions() == [hold]
    queued = post_mission(api, unique("queued"), second, [route("go", (5, 3))])["name"]
    expect(fleet.mission_row(queued)).to_have_attribute("data-state", "PENDING")  # live, filtered in
    assert fleet.listed_missions() == [queued, hold]  # not started: first
    fleet.filter_missions(name="short")
    expect(fleet.page.locator("#mission-rows tr")).to_have_count(1)
    assert fleet.listed_missions() == [short]


def test_an_operator_cancels_missions_from_the_page(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    robot = unique("cancel")
    simulator(f"{robot},0,0")
    create_robot(api, robot)
    running = post_mission(api, unique("running"), robot, [action("hold", should_fail=0, time=60)])["name"]
    queued = post_mission(api, unique("queued"), robot, [route("go", (1, 1))])["name"]
    wait_mission(api, running, {"RUNNING"})
    fleet.page.on("dialog", lambda dialog: dialog.accept())  # "Cancel mission ...?"

    fleet.select(robot)
    queue = fleet.page.locator("#robot-queue li")
    expect(queue).to_have_count(2)
    queue.filter(has_text=queued).get_by_role("button", name="Cancel", exact=True).click()
    assert wait_mission(api, queued)["status"]["state"] == "CANCELED"
    expect(queue).to_have_count(1)

    fleet.mission_row(running).get_by_role("button", name="Cancel", exact=True).click()
    assert wait_mission(api, running)["status"]["state"] == "CANCELED"
    expect(fleet.mission_row(running)).to_have_attribute("data-state", "CANCELED")
    expect(fleet.mission_row(running).get_by_role("button", name="Cancel", exact=True)).to_be_hidden()
    # Through the API, by the operator's session.
    cancels = WriteRecord.objects.filter(action=WriteAction.MISSION_CANCEL).values_list(
        "object_name", "actor"
    )
    assert sorted(cancels) == sorted([(queued, "user:operator"), (running, "user:operator")])


def test_an_operator_starts_and_stops_teleop_from_the_page(fleet: FleetPage, api, simulated_robot):
    robot = simulated_robot("teleop")
    wait_robot(api, robot, online=True)
    fleet.select(robot)
    expect(fleet.marker(robot)).to_have_attribute("data-condition", "idle")

    fleet.page.locator("#teleop-start").click()
    wait_robot(api, robot, state="TELEOP")
    expect(fleet.marker(robot)).to_have_attribute("data-condition", "teleop")

    fleet.page.locator("#teleop-stop").click()
    wait_robot(api, robot, state="IDLE")
    expect(fleet.marker(robot)).to_have_attribute("data-condition", "idle")
    expect(fleet.page.locator("#notice")).to_contain_text(f"Teleop STOP for {robot}: done")
    teleops = WriteRecord.objects.filter(action=WriteAction.ROBOT_TELEOP).values_list("actor", flat=True)
    assert list(teleops) == ["user:operator", "user:operator"]


def test_a_running_missions_route_is_drawn_driven_and_ahead_and_goes_when_it_ends(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    robot, idle, hall = unique("route"), unique("idle"), unique("hall")
    simulator(f"{robot},0,0", f"{idle},6,6", f"{hall},0,0,0,hall", extra=("--speed", "1"))
    for name in (robot, idle, hall):
        create_robot(api, name)
    expect(fleet.page.locator("#map-choice option")).to_have_text(["hall (1)", "map (2)"])
    across = post_mission(api, unique("across"), hall, [route("across", (30, 0), map_id="hall")])["name"]
    wait_mission(api, across, {"RUNNING"})
    fleet.select(robot)
    fleet.record(f'.route-waypoint[data-robot="{robot}"]', "data-progress", "data-waypoint")

    tree = [route("out", (2, 0), (2, 2)), route("back", (0, 2))]
    name = post_mission(api, unique("m"), robot, tree)["name"]
    expect(fleet.waypoints(robot)).to_have_count(3)
    expect(fleet.route(robot)).to_have_class(re.compile(r"\bselected\b"))
    # Changed while it runs: the page follows without a reload.
    update = {"back": {"waypoints": [{"x": 0, "y": 3, "theta": 0, "map_id": "map"}]}}
    assert api.post(f"/mission/{name}/update", update, format="json").status_code == 200
    expect(fleet.page.locator('.route-waypoint[data-waypoint="back.0"]')).to_have_attribute("data-y", "3")
    # On the robots' scale, y up: out.1 (2, 2) 2 m above out.0 (2, 0), back.0 (0, 3) 2 m left of out.1.
    dots = fleet.waypoint_centres(robot)
    metre = (dots["out.0"][1] - dots["out.1"][1]) / 2
    assert metre > 5
    assert dots["out.1"][0] == pytest.approx(dots["out.0"][0], abs=1)
    assert dots["back.0"][0] == pytest.approx(dots["out.1"][0] - 2 * metre, abs=1)
    assert dots["back.0"][1] == pytest.approx(dots["out.0"][1] - 3 * metre, abs=1)

    # Driving on: the first waypoint passed, the line driven up to the robot.
    first = fleet.page.locator('.route-waypoint[data-waypoint="out.0"]')
    expect(first).to_have_attribute("data-progress", "passed")
    assert "L" in fleet.route(robot, "route-driven").get_attribute("d")  # M x y L x y ...: a line
    # Only the robots on the map shown, only running missions' routes.
    expect(fleet.waypoints(hall)).to_have_count(0)
    expect(fleet.waypoints(idle)).to_have_count(0)

    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    expect(fleet.waypoints(robot)).to_have_count(0)
    expect(fleet.page.locator(f'[data-robot="{robot}"]:is(.route-ahead, .route-driven)')).to_have_count(0)
    progress = fleet.recorded()
    assert progress["out.0"] == ["ahead", "passed"], progress
    assert progress["out.1"] == ["ahead", "passed"], progress
    assert progress["back.0"][0] == "ahead", progress

    fleet.show_map("hall")
    expect(fleet.waypoints(hall)).to_have_count(1)
    expect(fleet.waypoints(hall)).to_have_attribute("data-x", "30")
    expect(fleet.route(hall)).to_have_count(1)


def stream_openings(fleet: FleetPage) -> list[float]:
    """When the page asked for GET /events from now on (monotonic seconds), as the browser sent them."""
    opened: list[float] = []
    fleet.page.on("request", lambda request: "/events" in request.url and opened.append(time.monotonic()))
    return opened


def expect_login_prompt(fleet: FleetPage) -> None:
    prompt = fleet.page.locator("#session-ended")
    expect(prompt).to_be_visible(timeout=60_000)
    expect(prompt).to_have_text("Your session has ended — log in again")
    link = prompt.get_by_role("link", name="log in again")
    expect(link).to_have_attribute("href", "/admin/login/?next=/fleet")
    expect(fleet.page.locator("#stream")).to_have_attribute("data-stream", "ended")


def test_a_stream_refused_after_a_logout_asks_for_a_login_and_is_not_retried(fleet: FleetPage):
    opened = stream_openings(fleet)
    with fleet.page.context.expect_page() as tab:  # another tab of the same browser: the same session
        fleet.page.evaluate("() => { window.open('/admin/'); }")
    other = tab.value
    other.get_by_role("button", name="Log out").click()
    expect(other.locator("#content")).to_contain_text("Logged out")

    # The server ends the open stream once it finds the session gone (FLEET_STREAM_CREDENTIALS_CHECK_SECONDS),
    # and EventSource's reconnection is refused.
    expect_login_prompt(fleet)
    refused = len(opened)
    assert refused >= 1
    # More than two of the 5 s a refused stream used to wait before it was tried again (Playwright's wait, so
    # that the page's requests are seen).
    fleet.page.wait_for_timeout(12_000)
    assert len(opened) == refused


def test_an_api_call_refused_for_an_ended_session_asks_for_a_login(fleet: FleetPage, api, simulated_robot):
    robot = simulated_robot("session")
    expect(fleet.marker(robot)).to_have_count(1)
    opened = stream_openings(fleet)
    Session.objects.all().delete()  # expired, or cleared on the server

    fleet.marker(robot).click()  # the panel asks GET /mission for the robot's queue: 401

    expect_login_prompt(fleet)
    # The stream is closed and not opened again (the server may have ended it first, and EventSource tried
    # once, refused).
    tried = len(opened)
    fleet.page.wait_for_timeout(3_000)  # more than the stream's retry (FLEET_EVENTS_RETRY_SECONDS)
    assert len(opened) == tried <= 1


def test_stations_are_drawn_with_who_holds_them_and_a_charging_robot_in_its_colour(
    fleet: FleetPage, api, simulator: Callable[..., Simulator], unique
):
    robot, charger, parking = unique("low"), unique("charger"), unique("parking")
    simulator(f"{robot},0,0,0,map,,20")  # at 20 %, below the minimum it gets: it goes to charge
    create_robot(api, robot, battery={"recommended_minimum": 30, "recommended_maximum": 90})
    expect(fleet.marker(robot)).to_have_count(1)  # the page shows the robots' map
    for name, kind, x in ((parking, "PARKING", -3), (charger, "CHARGER", 3)):
        body = {"name": name, "kind": kind, "pose": {"x": x, "y": 0, "theta": 0, "map_id": "map"}}
        assert api.post("/station", body, format="json").status_code == 200

    free = fleet.page.locator(f'.station[data-station="{parking}"]')
    expect(free).to_have_attribute("title", f"{parking}: PARKING, 0/1 held")
    expect(free).to_have_attribute("data-held", "no")
    held = fleet.page.locator(f'.station[data-station="{charger}"]')
    expect(held).to_have_attribute("title", f"{charger}: CHARGER, 1/1 held by {robot}")
    expect(held).to_have_attribute("data-held", "yes")
    expect(fleet.marker(robot)).to_have_attribute("data-condition", "charging")
