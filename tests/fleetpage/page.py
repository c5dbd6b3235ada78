"""The live fleet page in Chromium, read as a person reads it: the robots' markers and what their tooltips
say, the robot's panel, the mission list; and what changed on it meanwhile, recorded in the page by a
MutationObserver (so no state the page showed for a moment goes unseen by the test)."""

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from django.contrib.auth.models import User
from django.db import connections

from access.services import api_token_create
from tests.browser import chromium_page, log_in
from tests.granian_server import ASGI, GranianServer, granian_server

if TYPE_CHECKING:
    from playwright.sync_api import Locator, Page

PASSWORD = "fleet-page-password"

# Records, in the page, every value an attribute took: window.recorded[key] is the list of its values.
RECORD = """([selector, attribute, key]) => {
    window.recorded = {};
    const note = (element) => {
        const value = element.getAttribute(attribute);
        if (!element.matches(selector) || value === null) return;
        const values = (window.recorded[element.getAttribute(key)] ??= []);
        if (values[values.length - 1] !== value) values.push(value);
    };
    document.querySelectorAll(selector).forEach(note);
    new MutationObserver((mutations) => {
        for (const mutation of mutations) {
            if (mutation.type === "attributes") note(mutation.target);
            for (const added of mutation.addedNodes) {
                if (added.nodeType !== 1) continue;
                note(added);
                added.querySelectorAll(selector).forEach(note);
            }
        }
    }).observe(document.body, {subtree: true, childList: true, attributeFilter: [attribute]});
}"""


def staff_user(username: str = "operator", *, staff: bool = True) -> str:
    """A user who logs in with PASSWORD; a staff user unless `staff` is false."""
    User.objects.create_user(username, password=PASSWORD, is_staff=staff)
    return username


@dataclass
class FleetPage:
    page: "Page"
    url: str  # the server's

    def marker(self, robot: str) -> "Locator":
        return self.page.locator(f'.robot[data-robot="{robot}"]')

    def titles(self) -> dict[str, str]:
        """Every marker's tooltip, by robot."""
        return self.page.evaluate(
            "() => Object.fromEntries([...document.querySelectorAll('.robot[data-robot]')]"
            ".map((marker) => [marker.dataset.robot, marker.title]))"
        )

    def conditions(self) -> dict[str, str]:
        """Every marker's colour (idle, mission, teleop, error, offline), by robot."""
        return self.page.evaluate(
            "() => Object.fromEntries([...document.querySelectorAll('.robot[data-robot]')]"
            ".map((marker) => [marker.dataset.robot, marker.dataset.condition]))"
        )

    def centres(self) -> dict[str, tuple[float, float]]:
        """Where every marker is on the screen, in pixels (y down), by robot."""
        return self.page.evaluate(
            "() => Object.fromEntries([...document.querySelectorAll('.robot[data-robot]')].map((marker) => {"
            "  const box = marker.getBoundingClientRect();"
            "  return [marker.dataset.robot, [box.x + box.width / 2, box.y + box.height / 2]];"
            "}))"
        )

    def centre(self, robot: str) -> tuple[float, float]:
        """Where the robot's marker is on the screen, in pixels (y down)."""
        box = self.marker(robot).bounding_box()
        assert box is not None, f"{robot} is not on the map"
        return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2

    def show_map(self, map_id: str) -> None:
        self.page.locator("#map-choice").select_option(map_id)

    def select(self, robot: str) -> None:
        """Open the robot's panel by clicking its marker."""
        self.marker(robot).click()
        self.page.locator("#robot-name").filter(has_text=re.compile(f"^{re.escape(robot)}$")).wait_for()

    def route(self, robot: str, part: str = "route-ahead") -> "Locator":
        """A line of the robot's route on the map: `route-ahead` (still to drive) or `route-driven`."""
        return self.page.locator(f'.{part}[data-robot="{robot}"]')

    def waypoints(self, robot: str) -> "Locator":
        """The dots of the waypoints of the robot's route on the map."""
        return self.page.locator(f'.route-waypoint[data-robot="{robot}"]')

    def waypoint_centres(self, robot: str) -> dict[str, tuple[float, float]]:
        """Where each waypoint dot of the robot's route is on the screen, in pixels (y down), by waypoint
        (`<route node>.<index>`), read at one moment."""
        return self.page.evaluate(
            "(robot) => Object.fromEntries([...document.querySelectorAll('.route-waypoint')]"
            "  .filter((dot) => dot.dataset.robot === robot).map((dot) => {"
            "    const box = dot.getBoundingClientRect();"
            "    return [dot.dataset.waypoint, [box.x + box.width / 2, box.y + box.height / 2]];"
            "  }))",
            robot,
        )

    def mission_row(self, mission: str) -> "Locator":
        return self.page.locator(f'#mission-rows tr[data-mission="{mission}"]')

    def listed_missions(self) -> list[str]:
        """The mission list's rows, top to bottom."""
        return self.page.locator("#mission-rows tr").evaluate_all(
            "(rows) => rows.map((row) => row.dataset.mission)"
        )

    def filter_missions(self, *, state: str = "", robot: str = "", name: str = "") -> None:
        self.page.locator("#filter-state").select_option(state)
        self.page.locator("#filter-robot").fill(robot)
        self.page.locator("#filter-name").fill(name)

    def record(self, selector: str, attribute: str, key: str) -> None:
        """From now on, record each value `attribute` takes on the elements `selector` matches, by their
        attribute `key` (`recorded`)."""
        self.page.evaluate(RECORD, [selector, attribute, key])

    def recorded(self) -> dict[str, list[str]]:
        return self.page.evaluate("() => window.recorded")

    def mark_loaded(self) -> None:
        """Mark this load of the page: `still_loaded` is false once the page was loaded again."""
        self.page.evaluate("() => { window.sameLoad = true; }")

    def still_loaded(self) -> bool:
        return self.page.evaluate("() => window.sameLoad === true")


@contextmanager
def page_server(logs: Path, *, env: dict[str, str]) -> Iterator[GranianServer]:
    """The API process as `make run` has it (granian, fleet.asgi): the page, its static files (whitenoise),
    the REST API and GET /events, with `env` added to the test's environment."""
    _, token = api_token_create(name="page-server")
    with granian_server(ASGI, log=logs / "api.log", token=token, env=env) as server:
        yield server


@contextmanager
def fleet_page(url: str, *, username: str) -> Iterator[FleetPage]:
    """The live fleet page of the server at `url`, in Chromium, logged in as `username`. The database
    connections Django opened while the page was open (it keeps them per async context, and Playwright's
    event loop runs in this thread) are closed at the end: left open, they would outlive the test."""
    with chromium_page() as page:
        log_in(page, f"{url}/fleet", username=username, password=PASSWORD)
        page.wait_for_url(f"{url}/fleet")
        page.locator('#stream[data-stream="live"]').wait_for()
        try:
            yield FleetPage(page, url)
        finally:
            connections.close_all()
