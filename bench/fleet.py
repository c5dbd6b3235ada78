"""``python -m bench.fleet``: load a Mission Dispatch server with N fast fake robots and measure it.

One asyncio process simulates every robot over a few MQTT connections (``bench.robot``, ``bench.mqtt``)
and keeps each robot's mission queue at depth Q through the public REST API (``bench.api``). Timing is
taken on the robots' side only, so the same run can be pointed at any server with the reference's API
and VDA 5050 over MQTT. See bench/README.md for what is measured and how.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import re
import sys
import time
from collections import Counter, deque
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import orjson

from bench import measure, report
from bench.api import ApiError, DispatchApi
from bench.fleet_options import IDLE, RUN, Options, build_parser, options_from
from bench.mqtt import Connection
from bench.pool import Pool
from bench.robot import FACTSHEET_REQUEST, FakeRobot, OrderError, utc_now
from simulator.runner import BrokerSettings
from vda5050.models import ConnectionState

logger = logging.getLogger("bench")

STATE_TICK = 0.05  # s; periodic states go out in buckets this far apart, spreading the load
GRID_SPACING = 2.0  # m between robots' home positions
WAYPOINT_OFFSETS = ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0))  # m from home, route by route
QUIET_SECONDS = 2.0  # s without instant actions after which the server's greeting is over
SETTLED_READINGS = 2  # 1-s CPU readings in a row below --settle-cores after which the server has settled
CONNECT_TIMEOUT = 10.0  # s for a CONNACK or all SUBACKs of one connection
START_TIMEOUT = 60.0  # s for every robot's first order in the start phase
CLOSE_TIMEOUT = 10.0  # s to let queued messages leave before disconnecting
HTTP_DRAIN_TIMEOUT = 30.0  # s to wait for POSTs in flight at the end
CREATE_ATTEMPTS = 3
REPOST_DELAY = 1.0  # s before replacing a mission whose POST failed
MAX_LOGGED_ERRORS = 5  # of each kind; the rest are only counted
ORDER_ID_PATTERN = re.compile(r"(?P<mission>.+)-n\d+(?:-r\d+)?")  # ours and the reference's orderIds


class Load:
    """One robot and what the benchmark asked of it: outstanding missions, progress, pending timings."""

    __slots__ = (
        "connection",
        "current",
        "done_at",
        "missions",
        "name",
        "next_mission",
        "progress",
        "robot",
        "start_order_at",
        "start_sent_at",
        "starting",
        "state_topic",
        "x",
        "y",
    )

    def __init__(self, name: str, robot: FakeRobot, connection: Connection, x: float, y: float) -> None:
        self.name = name
        self.robot = robot
        self.connection = connection
        self.x, self.y = x, y
        self.state_topic = robot.topic + "state"
        self.missions: deque[str] = deque()  # posted and not yet finished, in posting order
        self.progress: dict[str, int] = {}  # orders finished per outstanding mission
        self.current: str | None = None  # the mission whose orders are arriving
        self.next_mission = 0
        self.done_at: float | None = None  # when the last order finished, if more work was queued
        self.starting = False  # start phase: waiting for the first mission's POST and first order
        self.start_sent_at: float | None = None
        self.start_order_at: float | None = None


@dataclass
class Window:
    """The measurement window (monotonic times) and what happened inside it."""

    start: float = float("inf")
    end: float = float("inf")
    orders_finished: int = 0
    missions_completed: int = 0
    step_latencies: list[float] = field(default_factory=list)
    tick_lags: list[float] = field(default_factory=list)

    def __contains__(self, moment: float) -> bool:
        return self.start <= moment < self.end


class Bench:
    """A whole run: robots, connections, missions, measurements."""

    def __init__(self, options: Options) -> None:
        self.options = options
        self.loop = asyncio.get_running_loop()
        self.api = DispatchApi(options.base_url, options.http_concurrency, options.api_token)
        broker = BrokerSettings(
            host=options.mqtt_host,
            port=options.mqtt_port,
            username=options.mqtt_username,
            password=options.mqtt_password,
            tls=options.mqtt_tls,
            ca_file=options.mqtt_ca_file,
        )
        tls = broker.tls_context()
        connection_count = -(-options.robots // options.robots_per_connection)
        self.connections = [
            Connection(f"{options.name_prefix}-{index}", broker, tls, self._on_message)
            for index in range(connection_count)
        ]
        self.pool = Pool(options.seed)
        self.loads = [self._new_load(index) for index in range(options.robots)]
        self.by_serial = {load.robot.serial: load for load in self.loads}
        self.created: list[str] = []  # robot names the server accepted
        self.last_instant_action = time.monotonic()
        self.settle_seconds = 0.0
        self.stopped = False
        self.counts: Counter[str] = Counter()
        self.window = Window()
        self.start_latencies: list[float] = []
        self.posting = False
        self.depth = 1
        self._posts: set[asyncio.Task[None]] = set()
        self._state_task: asyncio.Task[None] | None = None
        self.error_samples: dict[str, list[str]] = {}  # the first few messages of each kind of error

    @property
    def map_side(self) -> float:
        """--unbound: the square map's side (m), as large as the named runs' grid of homes."""
        return GRID_SPACING * max(1.0, self.options.robots**0.5)

    def _new_load(self, index: int) -> Load:
        side = max(1, round(self.options.robots**0.5))
        x, y = GRID_SPACING * (index % side), GRID_SPACING * (index // side)
        if self.options.unbound:  # spread over the map at seeded places
            x, y = self.pool.places.uniform(0, self.map_side), self.pool.places.uniform(0, self.map_side)
        name = f"{self.options.name_prefix}-{index}"
        robot = FakeRobot(
            serial=name,
            manufacturer=self.options.manufacturer,
            topic_prefix=self.options.mqtt_prefix,
            x=x,
            y=y,
        )
        connection = self.connections[index // self.options.robots_per_connection]
        return Load(name, robot, connection, x, y)

    # --- the run ---------------------------------------------------------------------------------------

    async def run(self) -> dict[str, Any]:
        options = self.options
        started_at = datetime.now(UTC)
        cpu_speed_ms = measure.cpu_speed_ms()  # before the fleet exists: no load of this run
        logger.info("CPU speed: %.1f ms of calibration work (lower is faster)", cpu_speed_ms)
        round_trips = measure.round_trip_us(options.probe_postgres, options.probe_redis)
        logger.info("round trips: %s", round_trips)
        try:
            await self._create_robots()
            await self._connect()
            self._state_task = self.loop.create_task(self._state_loop())
            await self._wait_online()
            await self._wait_quiet()
            await self.wait_settled()
            if options.unbound and options.mode != IDLE:
                await self._start_unbound()
            elif options.mode == RUN:
                await self._start_phase()
            if options.mode == RUN:
                self.depth = options.queue
                for load in self.loads:
                    self._top_up(load)
            logger.info("warming up for %.0f s", options.warmup)
            await asyncio.sleep(options.warmup)
            measured = await self._measure()
            self.posting = False
            failed = await self._failed_missions(started_at) if options.mode != IDLE else None
            if options.unbound:
                await self._read_bindings(started_at)
        finally:
            self.posting = False
            await self._shut_down()
        return self._result(started_at, {"cpu_speed_ms": cpu_speed_ms, **round_trips}, measured, failed)

    async def _create_robots(self) -> None:
        logger.info("creating %d robots %s-*", len(self.loads), self.options.name_prefix)
        await asyncio.gather(*(self._create_robot(load.name) for load in self.loads))

    async def _create_robot(self, name: str) -> None:
        """POST /robot, retried on errors (counted): a missing robot would spoil the whole run."""
        for attempt in range(CREATE_ATTEMPTS):
            try:
                await self.api.create_robot(name)
            except (ApiError, OSError) as exc:
                if attempt > 0 and isinstance(exc, ApiError) and "already exists" in exc.body:
                    break  # the failed attempt had created it after all
                if attempt == CREATE_ATTEMPTS - 1:
                    raise
                self._error("create_retries", f"POST /robot {name}: {exc}; retrying")
                await asyncio.sleep(REPOST_DELAY)
            else:
                break
        self.created.append(name)

    async def _connect(self) -> None:
        """Subscribe before the first state: the server asks for the factsheet once a robot is online."""
        for connection in self.connections:
            group = [load for load in self.loads if load.connection is connection]
            await connection.connect(CONNECT_TIMEOUT)
            topics = [load.robot.topic + kind for load in group for kind in ("order", "instantActions")]
            await connection.subscribe(topics, CONNECT_TIMEOUT)
            timestamp = utc_now()
            for load in group:
                robot = load.robot
                connection.publish(
                    robot.topic + "connection", robot.connection(ConnectionState.ONLINE), 1, True
                )
                connection.publish(load.state_topic, robot.state(timestamp))
        logger.info("%d robots on %d MQTT connections", len(self.loads), len(self.connections))

    async def _wait_online(self) -> None:
        waiting = {load.name for load in self.loads}
        deadline = self.loop.time() + self.options.online_timeout
        while waiting:
            waiting -= await self.api.online_robots(waiting)
            if not waiting:
                break
            if self.loop.time() > deadline:
                raise RuntimeError(f"{len(waiting)} robots not online after {self.options.online_timeout} s")
            await asyncio.sleep(0.5)
        logger.info("all %d robots online", len(self.loads))

    async def _wait_quiet(self) -> None:
        """Let the server's greeting (factsheetRequest to every new robot) pass before measuring."""
        deadline = self.loop.time() + self.options.online_timeout
        while self.loop.time() < deadline and time.monotonic() - self.last_instant_action < QUIET_SECONDS:
            await asyncio.sleep(0.1)

    async def wait_settled(self) -> None:
        """Let the server work off the fleet's arrival before measuring: each new robot costs it a few steps
        (coming online, its factsheet request and the answer), seconds of work for a thousand robots, and
        robots still arriving are not idle ones. Settled: the server's processes used less than
        `settle_cores` in SETTLED_READINGS 1-s readings in a row (a server on another machine reads 0).
        How long it took is reported as settle_seconds."""
        meter = measure.CpuMeter(self.options.process_groups)
        began = time.monotonic()
        deadline = began + self.options.online_timeout
        before, calm = meter.snapshot(), 0
        while calm < SETTLED_READINGS and time.monotonic() < deadline:
            at = time.monotonic()
            await asyncio.sleep(1.0)
            after = meter.snapshot()
            used = measure.usage(before, after, time.monotonic() - at)
            cores = sum(group["cores"] for name, group in used.items() if name != measure.GENERATOR)
            calm = calm + 1 if cores < self.options.settle_cores else 0
            before = after
        self.settle_seconds = round(time.monotonic() - began, 1)
        logger.info("server settled after %.1f s", self.settle_seconds)

    async def _start_phase(self) -> None:
        """Every robot idle gets one mission: POST -> first order received is the start latency."""
        logger.info("start phase: one mission for each idle robot")
        self.posting = True
        began = self.loop.time()
        for index, load in enumerate(self.loads):
            if self.options.start_rate > 0:
                await asyncio.sleep(max(0.0, began + index / self.options.start_rate - self.loop.time()))
            self._post(load, measure_start=True)
        deadline = self.loop.time() + START_TIMEOUT
        while any(load.starting for load in self.loads) and self.loop.time() < deadline:
            await asyncio.sleep(0.05)
        missing = sum(load.starting for load in self.loads)
        if missing:
            logger.warning("%d robots got no first order within %.0f s", missing, START_TIMEOUT)
            self.counts["start_timeouts"] = missing

    async def _start_unbound(self) -> None:
        """--unbound: one mission without a robot per robot, at --start-rate (a burst: as fast as the API
        takes them), destinations spread over the map; wait until each has reached a robot."""
        logger.info("start phase: %d unbound missions", len(self.loads))
        self.posting = self.options.mode == RUN  # a burst is the start phase's missions alone
        began = self.loop.time()
        for index in range(len(self.loads)):
            if self.options.start_rate > 0:
                await asyncio.sleep(max(0.0, began + index / self.options.start_rate - self.loop.time()))
            self._post_unbound(first=True)
        await self._drain_posts()
        deadline = self.loop.time() + START_TIMEOUT
        while self.pool.started - self.pool.first_orders.keys() and self.loop.time() < deadline:
            await asyncio.sleep(0.05)
        missing = len(self.pool.started - self.pool.first_orders.keys())
        if missing:
            logger.warning("%d unbound missions reached no robot within %.0f s", missing, START_TIMEOUT)
            self.counts["start_timeouts"] = missing

    async def _read_bindings(self, since: datetime) -> None:
        """When the server bound each start-phase mission (its status.assignment's first bound_at)."""
        try:
            missions = await self.api.missions(started_after=since.isoformat())
        except (ApiError, OSError) as exc:
            logger.warning("cannot list missions: %s", exc)
            return
        for mission in missions:
            bindings = mission.get("status", {}).get("assignment") or []
            if mission.get("name") in self.pool.started and bindings:
                bound_at = datetime.fromisoformat(bindings[0]["bound_at"].replace("Z", "+00:00"))
                self.pool.bound_at[mission["name"]] = bound_at.timestamp()

    async def _measure(self) -> dict[str, Any]:
        """The window, cut into slices: CPU, memory, step latency and orders per slice, and over all."""
        window = self.window
        meter = measure.CpuMeter(self.options.process_groups)
        ends = measure.slice_ends(self.options.duration, self.options.sample_every)
        logger.info("measuring for %.0f s in %d slices", self.options.duration, len(ends))
        published = measure.broker_publishes(self.options.probe_redis)
        first = previous = meter.snapshot()
        window.start = time.monotonic()
        window.end = window.start + self.options.duration
        before = self.counts.copy()
        previous_at, steps, orders = window.start, 0, 0
        series = []
        for end in ends:
            await asyncio.sleep(max(0.0, window.start + end - time.monotonic()))
            now = time.monotonic()
            snapshot = meter.snapshot()
            # Samples are appended in time order by this loop's callbacks, so counts split them by slice.
            series.append(
                measure.series_point(
                    now - window.start,
                    now - previous_at,
                    window.step_latencies[steps:],
                    window.orders_finished - orders,
                    measure.usage(previous, snapshot, now - previous_at),
                )
            )
            previous, previous_at = snapshot, now
            steps, orders = len(window.step_latencies), window.orders_finished
        seconds = previous_at - window.start
        window.end = min(window.end, time.monotonic())
        states = self.counts["states_published"] - before["states_published"]
        published_by_end = measure.broker_publishes(self.options.probe_redis)
        return {
            "seconds": seconds,
            "processes": measure.usage(first, previous, seconds),
            "busy_and_steal": measure.busy_and_steal(first.cpu_times, previous.cpu_times),
            "states_published": states,
            "tasks_sent": published_by_end - published
            if published is not None and published_by_end is not None
            else None,
            "series": series,
        }

    async def _failed_missions(self, since: datetime) -> dict[str, Any] | None:
        """The server's FAILED missions of this run (None if it cannot be asked)."""
        await self._drain_posts()
        try:
            missions = await self.api.missions(state="FAILED", started_after=since.isoformat())
        except (ApiError, OSError) as exc:
            logger.warning("cannot list failed missions: %s", exc)
            return None
        ours = [m for m in missions if m.get("name", "").startswith(self.options.name_prefix + "-")]
        reasons = Counter(str(m.get("status", {}).get("failure_reason")) for m in ours)
        return {"count": len(ours), "reasons": dict(reasons.most_common(5))}

    async def _shut_down(self) -> None:
        await self._drain_posts()
        if self._state_task is not None:
            self._state_task.cancel()
        self.stopped = True  # after OFFLINE a robot publishes nothing that would bring it back online
        for load in self.loads:
            robot = load.robot
            load.connection.publish(
                robot.topic + "connection", robot.connection(ConnectionState.OFFLINE), 1, True
            )
        if self.options.cleanup and self.created:
            logger.info("deleting %d robots", len(self.created))
            results = await asyncio.gather(
                *(self.api.delete_robot(name) for name in self.created), return_exceptions=True
            )
            self.counts["delete_errors"] = sum(isinstance(r, BaseException) for r in results)
            for load in self.loads:  # empty retained messages remove them from the broker
                load.connection.publish(load.robot.topic + "connection", b"", 1, True)
                load.connection.publish(load.robot.topic + "factsheet", b"", 1, True)
        await asyncio.gather(*(connection.close(CLOSE_TIMEOUT) for connection in self.connections))
        self.api.close()

    # --- messages from the server ----------------------------------------------------------------------

    def _on_message(self, topic: str, payload: bytes) -> None:
        now = time.monotonic()
        _, serial, kind = topic.rsplit("/", 2)
        load = self.by_serial.get(serial)
        if load is None or self.stopped:
            return
        try:
            message = orjson.loads(payload)
            if not isinstance(message, dict):
                raise OrderError("not a JSON object")
            if kind == "order":
                self._on_order(load, message, now)
            elif kind == "instantActions":
                self._on_instant_actions(load, message)
        except (orjson.JSONDecodeError, OrderError) as exc:
            self._error("malformed_messages", f"malformed {kind} for {serial}: {exc}")

    def _on_order(self, load: Load, order: dict[str, Any], now: float) -> None:
        if not load.robot.accept(order):
            self.counts["duplicate_orders"] += 1
            return
        self.counts["orders_received"] += 1
        if load.done_at is not None:
            if now in self.window:
                self.window.step_latencies.append(now - load.done_at)
            load.done_at = None
        if load.starting and load.start_order_at is None:
            load.start_order_at = now
            self._start_measured(load)
        mission = _mission_of(order["orderId"])
        if mission in self.pool.destinations and mission not in load.progress:  # bound to this robot
            self.pool.first_orders.setdefault(mission, (now, load))
            load.missions.append(mission)
            load.progress[mission] = 0
        if load.current is not None and load.current != mission:
            # The server runs one mission at a time: it has ended the current one (failed, canceled).
            self._forget(load, load.current)
            self.counts["missions_abandoned"] += 1
            self._top_up(load)
        load.current = mission if mission in load.progress else None
        if self.options.delay > 0:
            self._publish_state(load)
            self.loop.call_later(self.options.delay, self._finish_order, load, order["orderId"])
        else:
            self._finish_order(load, order["orderId"])

    def _finish_order(self, load: Load, order_id: str) -> None:
        if load.robot.order_id != order_id or self.stopped:
            return  # canceled meanwhile, or the run is over
        legs = load.robot.finish()
        now = time.monotonic()
        self._publish_state(load)
        self.counts["orders_finished"] += 1
        in_window = now in self.window
        self.window.orders_finished += in_window
        mission = _mission_of(order_id)
        if mission in load.progress:
            load.progress[mission] += legs
            if load.progress[mission] >= self.options.nodes:
                self._forget(load, mission)
                self.counts["missions_completed"] += 1
                self.window.missions_completed += in_window
        load.done_at = now if load.missions else None  # only then is a next order already due
        self._top_up(load)

    def _on_instant_actions(self, load: Load, message: dict[str, Any]) -> None:
        self.counts["instant_actions"] += 1
        self.last_instant_action = time.monotonic()
        robot = load.robot
        if FACTSHEET_REQUEST in robot.instant_actions(message):
            load.connection.publish(robot.topic + "factsheet", robot.factsheet(), 0, True)
        self._publish_state(load)

    def _publish_state(self, load: Load) -> None:
        load.connection.publish(load.state_topic, load.robot.state(utc_now()))
        self.counts["states_published"] += 1

    # --- missions --------------------------------------------------------------------------------------

    def _top_up(self, load: Load) -> None:
        if self.options.unbound:  # the pool, not the robot, holds the work: as many missions as robots x Q
            while self.posting and self.pool.outstanding < len(self.loads) * self.depth:
                self._post_unbound()
            return
        while self.posting and len(load.missions) < self.depth:
            self._post(load)

    def _post(self, load: Load, measure_start: bool = False) -> None:
        name = f"{load.name}-m{load.next_mission}"
        load.next_mission += 1
        load.missions.append(name)
        load.progress[name] = 0
        self.counts["missions_posted"] += 1
        body = mission_body(name, load.name, self.options, load.x, load.y)
        if measure_start:
            load.starting = True
        task = self.loop.create_task(self._send_mission(load, name, body, measure_start))
        self._posts.add(task)
        task.add_done_callback(self._posts.discard)

    def _post_unbound(self, first: bool = False) -> None:
        """A mission without a robot to a seeded place on the map; `first`: of the start phase (measured)."""
        pool = self.pool
        name = f"{self.options.name_prefix}-u{pool.posted}"
        x, y = pool.places.uniform(0, self.map_side), pool.places.uniform(0, self.map_side)
        pool.posted += 1
        pool.outstanding += 1
        pool.destinations[name] = (x, y)
        self.counts["missions_posted"] += 1
        if first:
            pool.started.add(name)
        task = self.loop.create_task(self._send_unbound(name, mission_body(name, None, self.options, x, y)))
        self._posts.add(task)
        task.add_done_callback(self._posts.discard)

    async def _send_unbound(self, name: str, body: dict[str, Any]) -> None:
        try:
            sent_at = await self.api.post_mission(body)
        except (ApiError, OSError) as exc:
            self._error("post_errors", f"POST /mission {name}: {exc}")
            self.pool.outstanding -= 1
            self.pool.started.discard(name)
            self.loop.call_later(REPOST_DELAY, self._top_up, self.loads[0])
            return
        # the POST's send time on the wall clock, to compare with the server's bound_at
        self.pool.sent_at[name] = (sent_at, time.time() - (time.monotonic() - sent_at))

    async def _send_mission(self, load: Load, name: str, body: dict[str, Any], measure_start: bool) -> None:
        try:
            sent_at = await self.api.post_mission(body)
        except (ApiError, OSError) as exc:
            self._error("post_errors", f"POST /mission {name}: {exc}")
            self._forget(load, name)
            load.starting = False
            self.loop.call_later(REPOST_DELAY, self._top_up, load)
            return
        if measure_start:
            load.start_sent_at = sent_at
            self._start_measured(load)

    def _start_measured(self, load: Load) -> None:
        """Start latency once both ends are known (the first order may arrive before the POST returns)."""
        if load.starting and load.start_sent_at is not None and load.start_order_at is not None:
            self.start_latencies.append(load.start_order_at - load.start_sent_at)
            load.starting = False

    def _forget(self, load: Load, mission: str) -> None:
        """The mission is over (or was never created): no longer outstanding."""
        if mission in load.progress:
            self.pool.outstanding -= mission in self.pool.destinations
            del load.progress[mission]
            load.missions.remove(mission)
        if load.current == mission:
            load.current = None

    # --- periodic states -------------------------------------------------------------------------------

    async def _state_loop(self) -> None:
        """Each robot publishes a state every 1/state_hz s, the fleet split into buckets a tick apart."""
        if self.options.state_hz <= 0:
            return
        period = 1.0 / self.options.state_hz
        tick = min(STATE_TICK, period)
        buckets = max(1, round(period / tick))
        groups = [self.loads[i::buckets] for i in range(buckets)]
        due = self.loop.time()
        for ticks in itertools.count():
            lag = self.loop.time() - due
            if time.monotonic() in self.window:
                self.window.tick_lags.append(lag)
            timestamp = utc_now()
            for load in groups[ticks % buckets]:
                load.connection.publish(load.state_topic, load.robot.state(timestamp))
            self.counts["states_published"] += len(groups[ticks % buckets])
            due += tick
            await asyncio.sleep(max(0.0, due - self.loop.time()))

    # --- helpers ---------------------------------------------------------------------------------------

    async def _drain_posts(self) -> None:
        """Wait for the POSTs in flight, so the server's view is complete."""
        if self._posts:
            await asyncio.wait(list(self._posts), timeout=HTTP_DRAIN_TIMEOUT)

    def _error(self, kind: str, message: str) -> None:
        self.counts[kind] += 1
        samples = self.error_samples.setdefault(kind, [])
        if len(samples) < MAX_LOGGED_ERRORS:
            samples.append(message[:500])
            logger.warning(message)

    def _result(
        self,
        started_at: datetime,
        calibration: dict[str, Any],
        measured: dict[str, Any],
        failed: dict[str, Any] | None,
    ) -> dict[str, Any]:
        options = self.options
        seconds = measured["seconds"]
        window = self.window
        lags = measure.latency_summary(window.tick_lags)
        return {
            "label": options.label,
            "mode": options.mode,
            "run_id": options.run_id,
            "started_at": started_at.isoformat(),
            "options": {**asdict(options), "output": str(options.output), "api_token": None},
            "machine": {**measure.machine(), **calibration, **measured["busy_and_steal"]},
            "window_seconds": round(seconds, 2),
            "settle_seconds": self.settle_seconds,
            "throughput": {
                "orders_per_second": round(window.orders_finished / seconds, 1),
                "missions_per_second": round(window.missions_completed / seconds, 2),
                "states_per_second": round(measured["states_published"] / seconds, 1),
            },
            "step_latency_ms": measure.latency_summary(window.step_latencies),
            "start_latency_ms": measure.latency_summary(self.start_latencies),
            "missions": {
                "posted": self.counts["missions_posted"],
                "completed": self.counts["missions_completed"],
                "completed_in_window": window.missions_completed,
                "failed": failed["count"] if failed is not None else None,
                "failure_reasons": failed["reasons"] if failed is not None else {},
                "abandoned": self.counts["missions_abandoned"],
            },
            "messages": {
                key: self.counts[key]
                for key in (
                    "orders_received",
                    "orders_finished",
                    "duplicate_orders",
                    "instant_actions",
                    "states_published",
                )
            },
            "errors": {
                **{
                    key: self.counts[key]
                    for key in (
                        "create_retries",
                        "post_errors",
                        "start_timeouts",
                        "malformed_messages",
                        "delete_errors",
                    )
                },
                "mqtt_disconnects": sum(connection.disconnects for connection in self.connections),
                "http_retries": self.api.retries,
                "samples": self.error_samples,
            },
            "cpu": measured["processes"],
            "cpu_per_order": measure.cpu_per_order(
                measured["processes"], window.orders_finished, calibration["cpu_speed_ms"]
            ),
            # Celery tasks sent in the window (steps, assignment and zone runs, notify calls) per order.
            "tasks_per_order": round(measured["tasks_sent"] / window.orders_finished, 3)
            if measured["tasks_sent"] is not None and window.orders_finished
            else None,
            "generator_tick_lag_ms": {"p99": lags["p99"], "max": lags["max"]},
            "assignment": self.pool.figures() if options.unbound else None,
            "series": measured["series"],
            "drift": measure.drift(measured["series"]),
        }


def mission_body(name: str, robot: str | None, options: Options, x: float, y: float) -> dict[str, Any]:
    """K route nodes of one waypoint each, hopping between points next to the robot's home (or, robot None:
    a mission without a robot, next to its destination (x, y))."""
    routes = []
    for index in range(options.nodes):
        dx, dy = WAYPOINT_OFFSETS[index % len(WAYPOINT_OFFSETS)]
        waypoint = {"x": x + dx, "y": y + dy, "theta": 0.0, "map_id": "map"}
        routes.append({"name": f"route{index}", "parent": "root", "route": {"waypoints": [waypoint]}})
    body = {"name": name, "robot": robot, "mission_tree": routes, "timeout": options.mission_timeout}
    return body if robot is not None else {key: value for key, value in body.items() if key != "robot"}


def _mission_of(order_id: str) -> str:
    match = ORDER_ID_PATTERN.fullmatch(order_id)
    return match["mission"] if match else order_id


# --- command line -----------------------------------------------------------------------------------------


def write_result(result: dict[str, Any], output: Path) -> Path:
    """``<output>/<stem>.json``, ``.md`` and ``-series.png`` (stem ``<mode>-n<N>-<run id>``); returns the
    JSON path."""
    output.mkdir(parents=True, exist_ok=True)
    stem = report.run_stem(result)
    path = output / f"{stem}.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    (output / f"{stem}.md").write_text(report.run_markdown(result))
    report.series_plot(result, output / f"{stem}-series.png")
    return path


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    sizes = [int(size) for size in args.sweep.split(",") if size.strip()] or [args.robots]
    paths = []
    for size in sizes:
        options = options_from(args, size, sweep=len(sizes) > 1)
        result = asyncio.run(_run(options))
        path = write_result(result, options.output)
        paths.append(path)
        logger.info("wrote %s\n%s", path, report.run_markdown(result))
    if len(paths) > 1:
        results = [json.loads(path.read_text()) for path in paths]
        table, plot = report.write_summary(results, args.output, f"sweep-{results[0]['run_id']}")
        logger.info("wrote %s and %s", table, plot)
    return 0


async def _run(options: Options) -> dict[str, Any]:
    return await Bench(options).run()  # built inside the loop: its connections belong to it


if __name__ == "__main__":
    sys.exit(main())
