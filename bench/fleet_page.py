"""How the live fleet page (/fleet) keeps up with a fleet that moves: N robots, every one moving at each
flush of their status, as the bridge writes it (`robot_status_write`, every --period seconds), watched by the
page in Debian's headless Chromium. Reported: the page's own work per animation frame (its flush), the frames
the browser drew per second, the main thread's long tasks (> 50 ms), and whether every marker ended where its
robot is.

Against a running API (`make run`, or the processes of deploy/Procfile) on the same database, with a staff
user's login; it makes robots `page-bench-0001`... (kept for the next run) and writes their status itself, so
no bridge or simulator is needed:

    FLEET_PAGE_PASSWORD=... .venv/bin/python -m bench.fleet_page --username admin --robots 1000

Results: bench/HISTORY.md, "Live fleet page".
"""

import argparse
import math
import os
import statistics
import time

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
# Playwright's sync API runs an event loop in this thread, where Django refuses database access; no Django
# code runs in that loop, so there is nothing for the guard to guard.
os.environ["DJANGO_ALLOW_ASYNC_UNSAFE"] = "true"
django.setup()

from playwright.sync_api import sync_playwright  # noqa: E402

from access.choices import command_actor  # noqa: E402
from robots.models import Robot  # noqa: E402
from robots.services import robot_create  # noqa: E402
from robots.status import robot_status_write, robots_came_online  # noqa: E402

PREFIX = "page-bench-"
COLUMNS = ("pose_x", "pose_y", "pose_theta", "pose_map_id", "battery_level")
LAST_FLUSH_WAIT = 60.0  # seconds the page may take to show the last flush
# Times each animation frame callback (the page's flush, and Leaflet's own) and counts the frames drawn.
FRAME_TIMING = """
window.frameWork = [];
window.frames = 0;
const requestFrame = window.requestAnimationFrame.bind(window);
window.requestAnimationFrame = (callback) => requestFrame((time) => {
    const start = performance.now();
    callback(time);
    window.frameWork.push(performance.now() - start);
});
const count = () => { window.frames += 1; requestFrame(count); };
requestFrame(count);
window.longTasks = [];
new PerformanceObserver((list) => window.longTasks.push(...list.getEntries().map((e) => e.duration)))
    .observe({type: "longtask", buffered: true});
"""


def pose(index: int, count: int, at: float) -> tuple[float, float, float]:
    """Robots on a square grid 3 m apart, each driving a circle of 1 m around its place."""
    side = math.ceil(math.sqrt(count))
    angle = at / 4 + index
    x = 3.0 * (index % side) + math.cos(angle)
    y = 3.0 * (index // side) + math.sin(angle)
    return x, y, angle + math.pi / 2


def robots(count: int) -> list[str]:
    names = [f"{PREFIX}{index:04d}" for index in range(1, count + 1)]
    existing = set(Robot.objects.filter(name__in=names).values_list("name", flat=True))
    for name in names:
        if name not in existing:
            robot_create(actor=command_actor("bench.fleet_page"), name=name, prefix=None, spec={})
    robots_came_online(names=names)
    return names


def write_status(names: list[str], at: float) -> None:
    rows = [
        (*pose(index, len(names), at), "bench", 50.0 + index % 50, name) for index, name in enumerate(names)
    ]
    robot_status_write(columns=COLUMNS, rows=rows)


def percentile(values: list[float], share: float) -> float:
    return sorted(values)[min(len(values) - 1, int(share * len(values)))] if values else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--url", default="http://127.0.0.1:5000")
    parser.add_argument("--username", required=True)
    parser.add_argument("--password", default=os.environ.get("FLEET_PAGE_PASSWORD"))
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--period", type=float, default=1.0, help="seconds between two status flushes")
    parser.add_argument("--seconds", type=float, default=30.0, help="how long the robots move")
    parser.add_argument(
        "--chromium", default=os.environ.get("PLAYWRIGHT_CHROMIUM_EXECUTABLE", "/usr/bin/chromium")
    )
    args = parser.parse_args()
    names = robots(args.robots)
    write_status(names, 0.0)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=args.chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.add_init_script(FRAME_TIMING)
        page.goto(f"{args.url}/fleet")
        page.locator("#id_username").fill(args.username)
        page.locator("#id_password").fill(args.password)
        page.locator("input[type=submit]").click()
        page.locator('#stream[data-stream="live"]').wait_for()
        page.locator(".robot[data-robot]").nth(len(names) - 1).wait_for(timeout=60_000)
        page.evaluate("() => { window.frameWork = []; window.frames = 0; window.longTasks = []; }")
        started = time.monotonic()
        flushes = 0
        while (at := time.monotonic() - started) < args.seconds:
            write_status(names, at)
            last = at
            flushes += 1
            time.sleep(max(0.0, args.period - (time.monotonic() - started - at)))
        elapsed = time.monotonic() - started
        work, frames, long_tasks = page.evaluate("() => [window.frameWork, window.frames, window.longTasks]")
        expected = [
            f"at ({x:.2f}, {y:.2f})" for x, y, _ in (pose(i, len(names), last) for i in range(len(names)))
        ]
        placed = 0
        while placed < len(names) and time.monotonic() - started - last < LAST_FLUSH_WAIT:
            titles = page.evaluate(
                "() => Object.fromEntries([...document.querySelectorAll('.robot[data-robot]')]"
                ".map((marker) => [marker.dataset.robot, marker.title]))"
            )
            placed = sum(where in titles.get(name, "") for name, where in zip(names, expected, strict=True))
        shown_after = time.monotonic() - started - last
        browser.close()
    print(f"{len(names)} robots, {flushes} status flushes in {elapsed:.1f} s (every {args.period} s)")
    print(
        f"frame callbacks: {len(work)}, work per callback p50 {statistics.median(work or [0]):.2f} ms, "
        f"p99 {percentile(work, 0.99):.2f} ms, max {max(work or [0]):.2f} ms"
    )
    print(f"frames drawn: {frames / elapsed:.1f} per second")
    print(f"long tasks (> 50 ms): {len(long_tasks)}, longest {max(long_tasks or [0]):.0f} ms")
    print(
        f"markers at their robot's last pose: {placed} of {len(names)}, {shown_after:.1f} s after its flush"
    )


if __name__ == "__main__":
    main()
