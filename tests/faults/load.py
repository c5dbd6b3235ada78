"""The fault suite's load: robots and missions posted through the REST API, every request recorded.

POSTs are retried while the API is away (refused connections, timeouts and 5xx are expected while a fault
is active). A POST whose first answer was a 5xx or no answer may still have created its mission, so the
retry keeps the name and takes "already exists" as success.
"""

from __future__ import annotations

import random
import threading
import time
from dataclasses import dataclass
from typing import Any

import requests

from simulator.config import RobotConfig
from tests.faults.checks import UNBOUND, HttpAttempt, PostedMission
from vda5050.polygons import Polygon, contains

MISSION_TIMEOUT = 900.0  # s: far beyond the suite's bounds; a mission that times out is a finding
RETRY_PERIOD = 0.3
# A RELEASE zone of capacity 1 (issue 46) among the first robots of the grid (`spread_robots`, 2 m apart):
# their routes near their starts cross it, none starts or stops in it (a route ending inside would hold it
# until its robot's next mission), and no charger (beside robots 1 and 2, on y = 0) is in it.
ZONE_ID = "crossing"
ZONE: tuple[tuple[float, float], ...] = ((0.3, 0.3), (1.7, 0.3), (1.7, 1.7), (0.3, 1.7))


def zone_set_body(name: str) -> dict[str, Any]:
    """The zone set of map `map` with `ZONE`, as POST /zone_set takes it."""
    vertices = [{"x": x, "y": y} for x, y in ZONE]
    zone = {"zone_id": ZONE_ID, "zone_type": "RELEASE", "release_loss_behavior": "STOP", "vertices": vertices}
    return {"name": name, "map_id": "map", "zones": [zone]}


@dataclass(frozen=True)
class PlannedMission:
    name: str
    robot: str | None  # None: posted without a robot, for assignment to bind (issue 41)
    tree: list[dict[str, Any]]

    def posted(self) -> PostedMission:
        leaves = tuple(
            (index, node["name"])
            for index, node in enumerate(self.tree)
            if "route" in node or "action" in node
        )
        return PostedMission(
            self.name, self.robot or UNBOUND, leaves, tuple(node["name"] for node in self.tree)
        )

    def body(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "robot": self.robot,
            "mission_tree": self.tree,
            "timeout": MISSION_TIMEOUT,
            "deadline": None,
            "needs_canceled": False,
        }


def plan_missions(
    rng: random.Random,
    robots: list[RobotConfig],
    count: int,
    *,
    unbound_share: float = 0.0,
    avoid: Polygon = (),
) -> list[PlannedMission]:
    """`count` missions spread over `robots` (round robin, in a shuffled order): 1-3 route leaves of 1-3
    waypoints each near the robot's start, none in `avoid` (a zone), and 0-2 `dummy_action` leaves that
    never fail, in random order. A share of them (`unbound_share`) is posted without a robot: assignment
    binds it."""
    order = list(robots)
    rng.shuffle(order)
    planned = []
    for k in range(count):
        robot = order[k % len(order)]
        leaves: list[dict[str, Any]] = []
        for r in range(rng.randint(1, 3)):
            waypoints = [
                {"x": x, "y": y, "theta": 0, "map_id": "map"}
                for x, y in (_near(rng, robot, avoid) for _ in range(rng.randint(1, 3)))
            ]
            leaves.append({"name": f"route{r}", "parent": "root", "route": {"waypoints": waypoints}})
        for a in range(rng.choice((0, 0, 1, 1, 2))):
            action = {
                "action_type": "dummy_action",
                "action_parameters": {"should_fail": 0, "time": round(rng.uniform(0.2, 1.0), 1)},
            }
            leaves.insert(
                rng.randint(0, len(leaves)), {"name": f"act{a}", "parent": "root", "action": action}
            )
        unbound = unbound_share > 0 and rng.random() < unbound_share
        planned.append(PlannedMission(f"fm{k:04d}", None if unbound else robot.name, leaves))
    return planned


def _near(rng: random.Random, robot: RobotConfig, avoid: Polygon) -> tuple[float, float]:
    """A point within 2 m of the robot's start (each axis, to 0.1 m), outside `avoid`."""
    while True:
        point = (round(robot.x + rng.uniform(-2, 2), 1), round(robot.y + rng.uniform(-2, 2), 1))
        if not avoid or not contains(avoid, point):
            return point


class Api:
    """A thread-safe REST client that records every request it makes (`attempts`)."""

    def __init__(self, base_url: str, token: str) -> None:
        self.base_url = base_url
        self.token = token
        self.attempts: list[HttpAttempt] = []
        self._lock = threading.Lock()
        self._local = threading.local()

    def _session(self) -> requests.Session:
        session = getattr(self._local, "session", None)
        if session is None:
            session = self._local.session = requests.Session()
            session.headers["Authorization"] = f"Bearer {self.token}"
        return session

    def request(
        self,
        method: str,
        path: str,
        body: Any = None,
        *,
        exists_after_retry: bool = False,
        timeout: float = 30,
    ) -> tuple[HttpAttempt, Any]:
        """One attempt; returns its record and the decoded JSON body (None if there is none)."""
        start = time.time()
        status, error, text, data = None, None, "", None
        try:
            response = self._session().request(method, self.base_url + path, json=body, timeout=(5, timeout))
            status, text = response.status_code, response.text
            try:
                data = response.json()
            except ValueError:
                data = None
        except requests.Timeout as exc:
            error = f"timeout: {exc}"
        except requests.ConnectionError as exc:
            error = f"connection: {exc}"
            self._local.session = None  # start over with fresh connections
        attempt = HttpAttempt(start, time.time(), method, path, status, error, text[:1000])
        if exists_after_retry and status == 400 and "already exists" in text:
            attempt = HttpAttempt(**{**attempt.__dict__, "exists_after_retry": True})
        with self._lock:
            self.attempts.append(attempt)
        return attempt, data

    def post_retrying(self, path: str, body: dict[str, Any], *, give_up_after: float) -> bool:
        """POST until the API takes it (or says a retried one already exists); False if it never does
        within `give_up_after` seconds or answers another 4xx."""
        deadline = time.monotonic() + give_up_after
        tried = False
        while True:
            attempt, _ = self.request("POST", path, body, exists_after_retry=tried)
            tried = True
            if attempt.status == 200 or attempt.exists_after_retry:
                return True
            if attempt.status is not None and 400 <= attempt.status < 500:
                return False
            if time.monotonic() >= deadline:
                return False
            time.sleep(RETRY_PERIOD)

    def get(self, path: str, *, give_up_after: float = 120) -> Any:
        """GET, retried until it answers 200 (a fault may be active); None on 404."""
        deadline = time.monotonic() + give_up_after
        while True:
            attempt, data = self.request("GET", path)
            if attempt.status == 200:
                return data
            if attempt.status == 404:
                return None
            if time.monotonic() >= deadline:
                raise RuntimeError(f"GET {path} did not succeed within {give_up_after:.0f} s: {attempt}")
            time.sleep(RETRY_PERIOD)

    def snapshot(self) -> list[HttpAttempt]:
        with self._lock:
            return list(self.attempts)
