"""Take the README's screenshot of the live fleet page (docs/fleet-page.png) while the simulator's robots
drive: against a running system (`make run`), with the development token and a staff user's login.

    .venv/bin/python manage.py createsuperuser          # once
    FLEET_PAGE_PASSWORD=... .venv/bin/python docs/screenshot.py --username admin

It gives every online robot a mission through the REST API (creating carter01 and carter02 first, as the
README's "Try it" does, if they do not exist), opens /fleet in Debian's Chromium (Playwright), opens
carter01's panel and takes the picture once carter01's mission is half done.
"""

import argparse
import os
import time
from pathlib import Path
from typing import Any

import requests
from playwright.sync_api import Page, sync_playwright

ROOT = Path(__file__).resolve().parents[1]
SHOWN = "carter01"  # the robot whose panel the picture shows
WAIT_SECONDS = 180


def waypoint(x: float, y: float) -> dict[str, Any]:
    return {"x": x, "y": y, "theta": 0, "map_id": "map"}


def shown_mission(x: float, y: float) -> list[dict[str, Any]]:
    """A pick-up and a delivery, with a fallback: sequence, selector, routes and actions."""
    return [
        {
            "name": "to_shelf",
            "parent": "root",
            "route": {"waypoints": [waypoint(x + 2, y), waypoint(x + 3, y - 2)]},
        },
        {"name": "pick", "parent": "root", "action": {"action_type": "pick", "action_parameters": {}}},
        {"name": "deliver", "parent": "root", "selector": {}},
        {
            "name": "via_aisle",
            "parent": "deliver",
            "route": {"waypoints": [waypoint(x - 2, y - 3), waypoint(x - 3, y)]},
        },
        {"name": "via_dock", "parent": "deliver", "route": {"waypoints": [waypoint(x, y + 3)]}},
        {"name": "drop", "parent": "root", "action": {"action_type": "drop", "action_parameters": {}}},
        {"name": "home", "parent": "root", "route": {"waypoints": [waypoint(x, y)]}},
    ]


def loop_mission(x: float, y: float) -> list[dict[str, Any]]:
    corners = [waypoint(x + 3, y), waypoint(x + 3, y + 3), waypoint(x, y + 3), waypoint(x, y)]
    return [{"name": "loop", "parent": "root", "route": {"waypoints": corners}}]


def post_missions(api: str, headers: dict[str, str]) -> str:
    """A mission for every online robot; the name of the shown robot's."""
    for name in ("carter01", "carter02"):
        requests.post(f"{api}/robot", json={"name": name}, headers=headers, timeout=10)  # 400 if it exists
    stamp = time.strftime("%H%M%S")
    robots = requests.get(f"{api}/robot", params={"online": "true"}, headers=headers, timeout=10).json()
    shown = ""
    for robot in robots:
        pose = robot["status"]["pose"]
        tree = (shown_mission if robot["name"] == SHOWN else loop_mission)(pose["x"], pose["y"])
        body = {
            "name": f"{robot['name']}-tour-{stamp}",
            "robot": robot["name"],
            "mission_tree": tree,
            "timeout": 600,
        }
        response = requests.post(f"{api}/mission", json=body, headers=headers, timeout=10)
        response.raise_for_status()
        if robot["name"] == SHOWN:
            shown = response.json()["name"]
    if not shown:
        raise SystemExit(f"{SHOWN} is not online: is the simulator running (make run)?")
    return shown


def wait_until_half_done(page: Page, mission: str) -> None:
    """Until the shown mission has completed its pick and drives its delivery."""
    page.locator("#tree-title").filter(has_text=f"Mission {mission}: RUNNING").wait_for(
        timeout=WAIT_SECONDS * 1000
    )
    page.locator('#robot-tree li[data-node="pick"][data-state="COMPLETED"]').wait_for(
        timeout=WAIT_SECONDS * 1000
    )
    page.locator('#robot-tree li[data-node="via_aisle"][data-state="RUNNING"]').wait_for(
        timeout=WAIT_SECONDS * 1000
    )
    time.sleep(1.5)  # a little way into the delivery


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--url", default="http://127.0.0.1:5000", help="the API server (make run: :5000)")
    parser.add_argument("--username", required=True, help="a staff user (manage.py createsuperuser)")
    parser.add_argument(
        "--password", default=os.environ.get("FLEET_PAGE_PASSWORD"), help="$FLEET_PAGE_PASSWORD"
    )
    parser.add_argument(
        "--token", default=os.environ.get("FLEET_API_TOKEN"), help="default: .fleet/dev-token"
    )
    parser.add_argument(
        "--chromium", default=os.environ.get("PLAYWRIGHT_CHROMIUM_EXECUTABLE", "/usr/bin/chromium")
    )
    parser.add_argument("--output", type=Path, default=ROOT / "docs" / "fleet-page.png")
    args = parser.parse_args()
    token = args.token or (ROOT / ".fleet" / "dev-token").read_text().strip()
    mission = post_missions(args.url, {"Authorization": f"Bearer {token}"})
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=args.chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(f"{args.url}/fleet")
        page.locator("#id_username").fill(args.username)
        page.locator("#id_password").fill(args.password)
        page.locator("input[type=submit]").click()
        page.locator('#stream[data-stream="live"]').wait_for()
        page.locator(f'.robot[data-robot="{SHOWN}"]').click()
        wait_until_half_done(page, mission)
        page.screenshot(path=args.output)
        browser.close()
    print(f"Wrote {args.output}")


if __name__ == "__main__":
    main()
