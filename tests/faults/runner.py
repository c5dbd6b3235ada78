"""One fault-suite run: a private stack, load, random faults from a seed, a quiet phase, then the checks.

The seed (`--seed`, else FLEET_FAULT_SEED, else random) fixes the fault plan (kind, time, downtime of each
fault: `random.Random(seed)`) and the load (robots' missions); timing on a shared machine does the rest,
so a replay injects the same faults into a run that is alike, not identical.
"""

from __future__ import annotations

import json
import os
import random
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tests.faults import checks
from tests.faults.checks import CheckResult, ServiceEvent, Window
from tests.faults.load import ZONE, ZONE_ID, Api, PlannedMission, plan_missions, zone_set_body
from tests.faults.observer import Observer
from tests.faults.stack import Stack, StackConfig, port_open, wait_until

SEED_ENV = "FLEET_FAULT_SEED"
# "simulator": every robot restarts (SIGKILL, then a fresh simulator with the robots where they last stood)
# A low robot's battery spec: its minimum above the simulator's 20 %, so it goes to charge once idle, and
# charges to 40 % (10 s at the simulator's 2 % per second).
LOW_BATTERY = {"critical_level": 5.0, "recommended_minimum": 25.0, "recommended_maximum": 40.0}
KINDS = ("api", "bridge", "worker", "beat", "notify", "postgres", "redis", "broker", "simulator")
# A POST must get through within this long, faults or not (a fault keeps a service down 5 s at most).
POST_GIVE_UP_SECONDS = 90.0


def seed_from_env(default: int | None = None) -> int:
    """FLEET_FAULT_SEED if set, else `default`, else a fresh random seed."""
    value = os.environ.get(SEED_ENV, "").strip()
    if value:
        return int(value)
    return default if default is not None else random.SystemRandom().randrange(1, 10**6)


@dataclass
class RunConfig:
    seed: int
    robots: int = 20
    missions: int = 300
    fault_seconds: float = 180.0
    quiet_seconds: float = 300.0  # bound on the quiet phase, which ends once every mission has ended
    keep_logs: Path | None = None
    speed: float = 3.0
    before_fraction: float = 0.35  # of the missions posted before the faults start; the rest during them
    grace: float = 2.0  # s after a restart of the API, PostgreSQL or Redis in which a 5xx is excused
    reconnect_grace: float = 6.0  # s after a broker restart for the publishers to reconnect (paho: 5 s max)
    fault_gap: tuple[float, float] = (5.0, 15.0)
    downtime: tuple[float, float] = (0.0, 5.0)
    settle_seconds: float = 3.0  # after the last mission ended, for the last messages to arrive
    charge_settle_seconds: float = 30.0  # bound, after the missions, for low robots to get their chargers
    unbound_share: float = 0.25  # of the missions posted without a robot, for assignment to bind
    chargers: int = 2  # chargers (capacity 1) among the robots (issue 44)
    low_share: float = 0.5  # of the robots whose minimum is above the simulator's 20 %: they go to charge


@dataclass(frozen=True)
class Fault:
    at: float  # s after the fault phase started
    kind: str
    downtime: float


def plan_faults(
    seed: int, seconds: float, gap: tuple[float, float] = (5, 15), downtime: tuple[float, float] = (0, 5)
) -> list[Fault]:
    """A fault every `gap` seconds while `seconds` last, each of a random kind, down for `downtime`."""
    rng = random.Random(seed)
    faults, at = [], 0.0
    while True:
        at += rng.uniform(*gap)
        if at >= seconds:
            return faults
        faults.append(Fault(round(at, 2), rng.choice(KINDS), round(rng.uniform(*downtime), 2)))


@dataclass
class Outcome:
    config: RunConfig
    results: list[CheckResult] = field(default_factory=list)
    faults: list[tuple[float, Fault]] = field(default_factory=list)  # (offset actually injected, fault)
    missions_posted: int = 0
    final_states: Counter[str] = field(default_factory=Counter)
    messages: Counter[str] = field(default_factory=Counter)
    requests: int = 0
    durations: dict[str, float] = field(default_factory=dict)
    logs: Path | None = None

    @property
    def ok(self) -> bool:
        return all(result.ok for result in self.results)

    def summary(self, *, max_problems: int = 25) -> str:
        seed = self.config.seed
        kinds = Counter(fault.kind for _, fault in self.faults)
        lines = [
            f"fault suite, seed {seed} (replay: {SEED_ENV}={seed} or --seed {seed}): "
            f"{'PASSED' if self.ok else 'FAILED'}",
            f"  stack: {self.config.robots} robots, {self.config.missions} missions, "
            f"{self.config.fault_seconds:g} s of faults, quiet phase bound {self.config.quiet_seconds:g} s",
            "  phases: " + ", ".join(f"{k} {v:.0f} s" for k, v in self.durations.items()),
            f"  faults injected ({len(self.faults)}): "
            + ", ".join(f"{k} x{n}" for k, n in sorted(kinds.items())),
            "  fault timeline: "
            + ", ".join(f"+{t:.1f}s {f.kind} ({f.downtime:.1f}s down)" for t, f in self.faults),
            f"  missions posted: {self.missions_posted}; "
            f"final states {dict(sorted(self.final_states.items()))}",
            f"  MQTT messages seen: {dict(sorted(self.messages.items()))}; HTTP requests: {self.requests}",
        ]
        for result in self.results:
            lines.append(f"  [{'ok' if result.ok else 'FAIL'}] {result.name}: {'; '.join(result.notes)}")
            for problem in result.problems[:max_problems]:
                lines.append(f"      seed {seed}: {problem}")
            if len(result.problems) > max_problems:
                lines.append(f"      ... and {len(result.problems) - max_problems} more")
        if self.logs is not None:
            lines.append(f"  logs: {self.logs}")
        return "\n".join(lines)


class Injector(threading.Thread):
    """Injects the planned faults one after another, relative to `started` (epoch s), and records when
    each service went down and when it served again."""

    def __init__(self, stack: Stack, plan: Sequence[Fault], started: float, log: list[str]) -> None:
        super().__init__(name="fault-injector", daemon=True)
        self.stack, self.plan, self.started, self.log = stack, plan, started, log
        self.events: list[ServiceEvent] = []
        self.injected: list[tuple[float, Fault]] = []
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            for fault in self.plan:
                delay = self.started + fault.at - time.time()
                if delay > 0:
                    time.sleep(delay)
                self.inject(fault)
        except BaseException as error:  # reported by the run, which then fails
            self.error = error

    def _event(self, component: str, kind: str) -> None:
        self.events.append(ServiceEvent(time.time(), component, kind))
        self.log.append(f"{time.time() - self.started:+8.2f}s {component} {kind}")

    def inject(self, fault: Fault) -> None:
        self.injected.append((time.time() - self.started, fault))
        self._event(fault.kind, "down")
        self.stack.take_down(fault.kind)
        time.sleep(fault.downtime)
        self.stack.bring_up(fault.kind)
        ready = {
            "api": self.stack.api_ready,
            "redis": self.stack.redis_ready,
            "broker": lambda: port_open(self.stack.mqtt_port),
        }.get(fault.kind)
        if ready is not None:
            wait_until(ready, f"{fault.kind} to serve again after its restart", timeout=90, period=0.05)
        self._event(fault.kind, "up")


class Poster(threading.Thread):
    """Posts missions at planned times (epoch s), each retried until the API takes it."""

    def __init__(self, api: Api, schedule: Sequence[tuple[float, PlannedMission]]) -> None:
        super().__init__(name="mission-poster", daemon=True)
        self.api, self.schedule = api, schedule
        self.posted: list[PlannedMission] = []
        self.unposted: list[str] = []

    def run(self) -> None:
        for at, mission in self.schedule:
            delay = at - time.time()
            if delay > 0:
                time.sleep(delay)
            if self.api.post_retrying("/mission", mission.body(), give_up_after=POST_GIVE_UP_SECONDS):
                self.posted.append(mission)
            else:
                self.unposted.append(mission.name)


class Reader(threading.Thread):
    """Reads through the API all along (a mission or a robot every `period` s), as clients watching
    their fleet do: every request is recorded, so a 5xx from a connection a fault left broken shows up
    however few missions are being posted at that moment."""

    def __init__(self, api: Api, missions: Sequence[PlannedMission], period: float = 0.25) -> None:
        super().__init__(name="api-reader", daemon=True)
        self.api, self.missions, self.period = api, missions, period
        self.stopping = threading.Event()
        self.rng = random.Random(0)
        self.stations: list[checks.StationSample] = []  # every answer of GET /station, for check 9

    def run(self) -> None:
        while not self.stopping.wait(self.period):
            mission = self.rng.choice(self.missions)
            path = f"/mission/{mission.name}" if self.rng.random() < 0.5 else f"/robot/{mission.robot}"
            self.api.request("GET", path, timeout=10)
            attempt, data = self.api.request("GET", "/station", timeout=10)
            if attempt.status == 200:
                self.stations += station_samples(data, attempt.start)

    def stop(self) -> None:
        self.stopping.set()
        self.join(timeout=15)


def station_samples(stations: list[dict[str, Any]], at: float) -> list[checks.StationSample]:
    """An answer of GET /station (asked at `at`) as samples for the station checks."""
    return [
        checks.StationSample(at, s["name"], s["kind"], s["capacity"], tuple(s["status"]["reservations"]))
        for s in stations
    ]


def stations_now(api: Api) -> list[checks.StationSample]:
    at = time.time()
    return station_samples(api.get("/station") or [], at)


def robots_now(api: Api) -> dict[str, dict[str, Any]]:
    return {robot["name"]: robot for robot in api.get("/robot") or []}


def run(config: RunConfig, *, echo: bool = True) -> Outcome:
    """One run; the Outcome holds every check's result. The run itself raises only if it could not go on
    (a service that never came back, say), with the seed in the message."""
    try:
        return _run(config, echo=echo)
    except Exception as error:
        raise RuntimeError(f"fault suite seed {config.seed}: the run could not go on: {error}") from error


def _run(config: RunConfig, *, echo: bool) -> Outcome:

    def say(text: str) -> None:
        if echo:
            print(f"[faults seed {config.seed}] {text}", flush=True)

    outcome = Outcome(config, logs=config.keep_logs)
    plan = plan_faults(config.seed, config.fault_seconds, config.fault_gap, config.downtime)
    say(f"seed {config.seed}: {len(plan)} faults planned: " + ", ".join(f"+{f.at:g}s {f.kind}" for f in plan))
    t0 = time.time()
    timeline: list[str] = []
    with Stack(StackConfig(robots=config.robots, speed=config.speed, keep_logs=config.keep_logs)) as stack:
        say(
            f"stack up in {time.time() - t0:.0f} s: API :{stack.api_port}, PostgreSQL :{stack.pg_port}, "
            f"Redis :{stack.redis_port}, Mosquitto :{stack.mqtt_port}; logs in {stack.logs}"
        )
        outcome.durations["setup"] = time.time() - t0
        observer = Observer(stack.mqtt_port)
        stack.poses = observer.poses
        try:
            observer.wait_subscribed()
            api = Api(stack.api_url, stack.api_token)
            battery_rng = random.Random(f"batteries-{config.seed}")
            for robot in stack.robots:
                low = battery_rng.random() < config.low_share
                body = {"name": robot.name, "battery": LOW_BATTERY if low else {}}
                if not api.post_retrying("/robot", body, give_up_after=60):
                    raise RuntimeError(f"robot {robot.name} could not be created: {api.snapshot()[-1]}")
            for index, robot in enumerate(stack.robots[: config.chargers]):
                pose = {"x": robot.x + 1.0, "y": robot.y, "theta": 0.0, "map_id": robot.map_id}
                body = {"name": f"charger{index}", "kind": "CHARGER", "pose": pose}
                if not api.post_retrying("/station", body, give_up_after=60):
                    raise RuntimeError(f"charger{index} could not be created: {api.snapshot()[-1]}")
            for path, body in (("/zone_set", zone_set_body("faults")), ("/zone_set/faults/enable", {})):
                if not api.post_retrying(path, body, give_up_after=60):
                    raise RuntimeError(f"POST {path} did not succeed: {api.snapshot()[-1]}")

            def all_online() -> bool:
                robots = api.get("/robot") or []
                return sum(1 for r in robots if r["status"]["online"]) >= config.robots

            wait_until(all_online, "every simulated robot online", timeout=60, period=0.5)
            planned = plan_missions(
                random.Random(f"load-{config.seed}"),
                stack.robots,
                config.missions,
                unbound_share=config.unbound_share,
                avoid=ZONE,
            )
            before = round(len(planned) * config.before_fraction)
            pre = Poster(api, [(0.0, m) for m in planned[:before]])
            pre.run()
            started = time.time()
            outcome.durations["robots and first missions"] = started - t0 - outcome.durations["setup"]
            during = planned[before:]
            spacing = config.fault_seconds / max(1, len(during))
            poster = Poster(api, [(started + i * spacing, m) for i, m in enumerate(during)])
            injector = Injector(stack, plan, started, timeline)
            say(f"{before} missions posted; fault phase of {config.fault_seconds:g} s starts")
            reader = Reader(api, planned[:before] or planned)
            poster.start()
            injector.start()
            reader.start()
            injector.join()
            if injector.error is not None:
                raise RuntimeError(f"the fault injector failed: {injector.error!r}") from injector.error
            remaining = started + config.fault_seconds - time.time()
            if remaining > 0:
                time.sleep(remaining)
            poster.join()
            faults_end = time.time()
            outcome.durations["faults"] = faults_end - started
            say(f"faults over ({len(injector.injected)} injected); quiet phase until every mission ended")
            posted = pre.posted + poster.posted
            names = {m.name for m in posted}

            def all_ended() -> bool:
                missions = api.get("/mission") or []
                done = sum(
                    1 for m in missions if m["name"] in names and m["status"]["state"] in checks.TERMINAL
                )
                return done >= len(names)

            try:
                wait_until(all_ended, "every mission to end", timeout=config.quiet_seconds, period=2)
            except RuntimeError:
                say(f"not every mission ended within {config.quiet_seconds:g} s of the faults stopping")
            try:
                wait_until(
                    lambda: checks.check_low_robots_charge(robots_now(api), stations_now(api)).ok,
                    "every low robot to hold a charger or wait for a full one",
                    timeout=config.charge_settle_seconds,
                    period=1,
                )
            except RuntimeError:
                say(f"low robots without a charger {config.charge_settle_seconds:g} s after the missions")
            time.sleep(config.settle_seconds)
            reader.stop()
            waited = time.time() - faults_end
            outcome.durations["quiet"] = waited
            final_list = api.get("/mission") or []
            final = {m["name"]: m for m in final_list if m["name"] in names}
            trips = frozenset(m["name"] for m in final_list if m.get("purpose") is not None)
            stations_final = stations_now(api)
            for name in names - set(final):
                final[name] = api.get(f"/mission/{name}")
            robots_final = {r["name"]: r for r in api.get("/robot") or []}
            running_at_end = stack.running_now()
        finally:
            stack.stop_watching()
            observer.close()
        messages = observer.snapshot()
        blind = observer.blind()
        events = injector.events
        exits = list(stack.exits)
        attempts = api.snapshot()
        _write_recordings(stack.logs, messages, events, attempts, timeline, blind, started)
    broker_down = checks.impaired_windows(events, grace=0, components=("broker",))
    broker_excuse = [Window(w.start, w.end + config.reconnect_grace, "broker outage") for w in broker_down]
    posted_missions = [m.posted() for m in posted]
    restarts = checks.impaired_windows(events, grace=0, components=("simulator",))
    origin = started
    outcome.results = [
        checks.check_missions(
            posted_missions,
            final,
            waited=waited,
            robots=robots_final,
            unposted=poster.unposted + pre.unposted,
            restarts=restarts,
        ),
        checks.check_order_copies(messages, origin),
        checks.check_no_order_while_busy(messages, [*blind, *broker_down], origin),
        checks.check_leaves(
            posted_missions, final, messages, [*blind, *broker_down], origin, restarts=restarts, trips=trips
        ),
        checks.check_bindings(posted_missions, final, messages),
        checks.check_header_ids(
            messages, [*blind, *broker_excuse], since=observer.started_at, origin=origin, events=events
        ),
        checks.check_http(attempts, events, grace=config.grace, origin=origin),
        checks.check_processes(exits, running_at_end, origin),
        checks.check_station_capacity(reader.stations, origin),
        checks.check_zone_capacity(messages, {ZONE_ID: ZONE}, [*blind, *broker_excuse, *restarts], origin),
        checks.check_low_robots_charge(robots_final, stations_final),
    ]
    outcome.faults = injector.injected
    outcome.missions_posted = len(posted)
    outcome.final_states = Counter(str((m or {}).get("status", {}).get("state")) for m in final.values())
    outcome.messages = Counter(m.kind for m in messages)
    outcome.requests = len(attempts)
    outcome.durations["total"] = time.time() - t0
    return outcome


def _write_recordings(
    logs: Path,
    messages: Sequence[checks.WireMessage],
    events: Sequence[ServiceEvent],
    attempts: Sequence[checks.HttpAttempt],
    timeline: Sequence[str],
    blind: Sequence[Window],
    origin: float,
) -> None:
    """What the run recorded, next to the process logs (kept with --keep-logs)."""
    with (logs / "wire.jsonl").open("w") as out:
        for message in messages:
            record = {"t": message.t, "dt": round(message.t - origin, 3), "topic": message.topic}
            out.write(json.dumps({**record, "data": message.data}) + "\n")
    with (logs / "http.jsonl").open("w") as out:
        for attempt in attempts:
            out.write(json.dumps(asdict(attempt)) + "\n")
    with (logs / "faults.log").open("w") as out:
        out.write(f"origin {origin:.3f} (epoch s); offsets relative to the fault phase start\n")
        out.writelines(f"{line}\n" for line in timeline)
        out.writelines(f"event {e.t:.3f} ({e.t - origin:+.2f}s) {e.component} {e.kind}\n" for e in events)
        out.writelines(
            f"observer blind {w.start:.3f}..{w.end:.3f} ({w.start - origin:+.2f}s..{w.end - origin:+.2f}s)\n"
            for w in blind
        )
