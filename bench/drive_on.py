"""Routes without stops, measured: from the end of one route leaf to motion on the next, in real processes.

Starts the dispatch path of a checkout (`--code`, default this one: the bridge, a step worker and beat, as
`deploy/Procfile` runs them) against a database and Redis database of its own, and the simulator with one
robot; posts missions of consecutive one-waypoint route leaves (a square back to the robot's home) one after
another, and reads the robot's own states on the broker. For every leaf but a mission's last:

- the end: the robot's timestamp of its first state that reports the leaf's last node reached
  (`lastNodeId`; the simulator sends a state in the tick it reaches a node);
- the go: the robot's timestamp of its first state from then on that reports it driving with nodes left
  to go (the state that reaches the node reports the tick's motion onto it);
- the gap: go - end, and whether a state in between showed it standing (`driving` false).

Both times come from the robot's clock, so the broker and our processes add nothing but what they delay.
A gap of 0 is the robot reaching the node and driving on within the same motion tick.

    .venv/bin/python -m bench.drive_on --label branch
    mkdir /tmp/md-main && git archive main | tar -x -C /tmp/md-main
    .venv/bin/python -m bench.drive_on --code /tmp/md-main --label main

Prints one JSON line per run (and appends it to `--output`); the machine's calibration figure
(`bench.measure.cpu_speed_ms`) is taken at the run's start.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import secrets
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import orjson
import paho.mqtt.client as mqtt

from bench.measure import cpu_speed_ms
from bench.processes import running

ROOT = Path(__file__).resolve().parent.parent
VENV_BIN = Path(sys.executable).parent
ENV = {
    "FLEET_DB_NAME": "mission_dispatch_drive_on",
    "FLEET_REDIS_URL": "redis://127.0.0.1:6379/13",
    "FLEET_LOG_LEVEL": "WARNING",
    "FLEET_SECRET_KEY": secrets.token_urlsafe(50),
    "DJANGO_SETTINGS_MODULE": "fleet.settings",
}
SIDE = 2.0  # m, each leaf of the square
NODE_ID = re.compile(r"(?P<mission>.+)-n(?P<leaf>\d+)-r\d+-s(?P<sequence>\d+)")


def server_processes(code: Path, schedule: Path) -> dict[str, list[str]]:
    """The dispatch path as `deploy/Procfile` runs it (no API: missions are created through the services)."""
    celery = str(VENV_BIN / "celery")
    worker = ["--pool", "threads", "--concurrency", "12", "--without-gossip", "--without-mingle"]
    return {
        "bridge": [sys.executable, "manage.py", "mqtt_bridge"],
        "worker": [celery, "-A", "fleet", "worker", "-Q", "steps,notify", *worker, "-n", "drive-on@%h"],
        "beat": [celery, "-A", "fleet", "beat", "--schedule", str(schedule)],
    }


class States:
    """The robot's states as the broker passes them on."""

    def __init__(self, serial: str, host: str, port: int) -> None:
        self.states: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=f"drive-on-{uuid.uuid4().hex[:8]}"
        )
        self.client.on_connect = lambda client, *args: client.subscribe(f"+/+/+/{serial}/state")
        self.client.on_message = self._on_message
        self.client.connect(host, port)
        self.client.loop_start()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        with self._lock:
            self.states.append(orjson.loads(message.payload))

    def snapshot(self) -> list[dict[str, Any]]:
        with self._lock:
            return list(self.states)

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def gaps(states: Sequence[dict[str, Any]], mission: str, leaves: int) -> list[tuple[float, bool]]:
    """(seconds from the end of leaf i to the robot driving again, whether it stood in between) for every
    leaf i but the last of `mission`, from the robot's states in the order it sent them."""
    ordered = sorted(states, key=lambda s: s["headerId"])
    found = []
    for leaf in range(leaves - 1):
        end = next(
            (
                i
                for i, s in enumerate(ordered)
                if (match := NODE_ID.fullmatch(s.get("lastNodeId") or ""))
                and match["mission"] == mission
                and int(match["leaf"]) == leaf
                and int(match["sequence"]) > 0
            ),
            None,
        )
        if end is None:
            continue
        go = next(
            (i for i in range(end, len(ordered)) if ordered[i]["driving"] and ordered[i]["nodeStates"]),
            None,
        )
        if go is None:
            continue
        seconds = (_epoch(ordered[go]["timestamp"]) - _epoch(ordered[end]["timestamp"])).total_seconds()
        found.append((seconds, any(not s["driving"] for s in ordered[end:go])))
    return found


def _epoch(timestamp: str) -> datetime:
    return datetime.fromisoformat(timestamp.replace("Z", "+00:00"))


def run(args: argparse.Namespace) -> dict[str, Any]:
    code = args.code.resolve()
    os.environ.update(ENV)  # this process's settings too: it creates the robot and the missions
    env = {**os.environ, "PYTHONPATH": str(code)}
    subprocess.run([sys.executable, "deploy/ensure_database.py"], cwd=ROOT, env=env, check=True)
    subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env, check=True)
    import django

    django.setup()
    import redis
    from django.conf import settings

    from missions.models import Mission
    from missions.services import mission_create
    from robots.models import Robot
    from robots.services import robot_create

    redis.Redis.from_url(ENV["FLEET_REDIS_URL"]).flushdb()
    speed_ms = cpu_speed_ms()
    robot = f"driveon-{uuid.uuid4().hex[:6]}"
    logs = args.logs / f"{args.label}-{robot}"
    simulator = [
        sys.executable,
        "-m",
        "simulator",
        "--robots",
        f"{robot},0,0",
        "--tick_period",
        str(args.tick),
        "--speed",
        str(args.speed),
        "--mqtt_host",
        settings.MQTT_HOST,
        "--mqtt_port",
        str(settings.MQTT_PORT),
        "--log_level",
        "WARNING",
    ]
    commands = {**server_processes(code, logs / "beat-schedule"), "simulator": simulator}
    states = States(robot, settings.MQTT_HOST, settings.MQTT_PORT)
    found: list[tuple[float, bool]] = []
    try:
        with running(commands, code, env, logs):
            robot_create(actor="bench", name=robot, prefix=None, spec={})
            _wait(lambda: Robot.objects.filter(name=robot, online=True).exists(), "the robot online")
            square = [(SIDE, 0.0), (SIDE, SIDE), (0.0, SIDE), (0.0, 0.0)]
            for number in range(args.missions):
                name = f"{robot}-m{number}"
                tree = [
                    {
                        "name": f"leg{i}",
                        "route": {"waypoints": [{"x": x, "y": y, "theta": 0.0, "map_id": "map"}]},
                    }
                    for i, (x, y) in enumerate(square)
                ]
                mission_create(
                    actor="bench",
                    name=name,
                    prefix=None,
                    spec={"robot": robot, "mission_tree": tree, "timeout": 600},
                )
                _wait(
                    lambda name=name: Mission.objects.filter(name=name, state="COMPLETED").exists(),
                    f"mission {name} completed",
                )
                time.sleep(1.0)  # the robot's last states of the mission
                found += gaps(states.snapshot(), name, len(square))
    finally:
        states.close()
    seconds = [gap for gap, _ in found]
    return {
        "label": args.label,
        "code": str(code),
        "at": datetime.now().astimezone().isoformat(timespec="seconds"),
        "cpu_speed_ms": speed_ms,
        "tick_s": args.tick,
        "speed_m_s": args.speed,
        "gaps": len(seconds),
        "stops": sum(stood for _, stood in found),
        "gap_ms": {
            "median": round(statistics.median(seconds) * 1000, 1) if seconds else None,
            "mean": round(statistics.fmean(seconds) * 1000, 1) if seconds else None,
            "min": round(min(seconds) * 1000, 1) if seconds else None,
            "max": round(max(seconds) * 1000, 1) if seconds else None,
        },
    }


def _wait(condition: Any, what: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.1)
    raise RuntimeError(f"timed out waiting for {what}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--code", type=Path, default=ROOT, help="checkout whose server processes run")
    parser.add_argument("--label", default="this checkout")
    parser.add_argument("--missions", type=int, default=5, help="missions of 4 leaves, one after another")
    parser.add_argument("--tick", type=float, default=0.05, help="the simulator's motion tick, s")
    parser.add_argument("--speed", type=float, default=1.0, help="the simulator's speed, m/s")
    parser.add_argument("--logs", type=Path, default=Path("/tmp/drive-on-logs"))
    parser.add_argument("--output", type=Path, default=None, help="append the JSON line to this file")
    args = parser.parse_args(argv)
    result = run(args)
    line = json.dumps(result)
    print(line)
    if args.output is not None:
        with args.output.open("a") as output:
            output.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
