"""A/B of the API's CPU per REST request: two source trees' API servers side by side, interleaved.

Both trees' API (`deploy/Procfile`'s granian command) run at once on ports of their own, against one
database and one Redis database; rounds of requests (`--clients` concurrent clients, POST /mission, or
GET /robot with `--get`) go to one server, then the other, alternating, and each round's CPU of the server's
processes (from /proc) is divided by its requests. Rounds of a few seconds, interleaved, put both
sides on the same machine speed: a day's drift of up to 2x, and the minute-to-minute swings of a shared
VM, fall on both alike. No worker runs: the missions queue behind each other (a robot's first one asks
for a step, which waits in Redis). Run on a database of its own, migrated, with nothing else running:

    FLEET_SECRET_KEY=... FLEET_DB_NAME=md_rest_cpu FLEET_REDIS_URL=redis://127.0.0.1:6379/4 \\
        .venv/bin/python -m bench.rest_cpu --a . --b /tmp/md-base --rounds 20

`--b` is another checkout (e.g. `git archive <rev> | tar -x -C /tmp/md-base` with a link to this
`.venv`). Results: bench/HISTORY.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path

import django
import requests

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

from access.services import api_token_create  # noqa: E402
from bench.api_layout import Server, served  # noqa: E402
from bench.measure import CpuMeter, cpu_speed_ms, interleaved  # noqa: E402
from bench.suite import api_command  # noqa: E402
from missions.models import Mission  # noqa: E402

PREFIX = "rest-cpu-"


def cpu_meter(servers: dict[str, Server]) -> CpuMeter:
    """`bench.measure`'s meter of each side's server: its processes are those serving its port (the
    granian workers are forks, with its command line)."""
    return CpuMeter(
        {side: rf"granian.* --port {server.url.rpartition(':')[2]} " for side, server in servers.items()}
    )


def request_round(
    url: str, headers: dict[str, str], clients: int, requests_per_client: int, tag: str, get: bool
) -> None:
    tree = [{"name": "go", "route": {"waypoints": [{"x": 1, "y": 1}]}}]

    def client(number: int) -> None:
        with requests.Session() as session:
            for i in range(requests_per_client):
                if get:
                    response = session.get(
                        f"{url}/robot?names={PREFIX}r{i % 50}", headers=headers, timeout=30
                    )
                else:
                    body = {"robot": f"{PREFIX}r{i % 50}", "name": f"{PREFIX}{tag}-{number}-{i}"}
                    response = session.post(
                        f"{url}/mission", json={**body, "mission_tree": tree}, headers=headers, timeout=30
                    )
                response.raise_for_status()

    with ThreadPoolExecutor(clients) as pool:
        list(pool.map(client, range(clients)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", type=Path, required=True, help="one source tree (this checkout: .)")
    parser.add_argument("--b", type=Path, required=True, help="the other")
    parser.add_argument("--rounds", type=int, default=20, help="rounds per side, alternating")
    parser.add_argument("--requests", type=int, default=400, help="requests per round")
    parser.add_argument("--clients", type=int, default=1, help="concurrent clients")
    parser.add_argument("--get", action="store_true", help="GET /robot instead of POST /mission")
    parser.add_argument("--logs", type=Path, default=Path("/tmp/rest-cpu-logs"))
    args = parser.parse_args()
    args.logs.mkdir(parents=True, exist_ok=True)
    Mission.objects.filter(name__startswith=PREFIX).delete()
    _, token = api_token_create(name=f"{PREFIX}{time.time_ns()}")
    headers = {"Authorization": f"Bearer {token}"}
    per_client = args.requests // args.clients
    calibration = cpu_speed_ms()
    with ExitStack() as stack:
        servers = {
            side: stack.enter_context(
                served(api_command, dict(os.environ), args.logs / f"{side}.log", cwd=tree.resolve())
            )
            for side, tree in (("a", args.a), ("b", args.b))
        }
        for side, server in servers.items():
            request_round(server.url, headers, args.clients, per_client, f"{side}-warm", args.get)
        spent = interleaved(
            ["a", "b"],
            args.rounds,
            cpu_meter(servers),
            lambda side, number: request_round(
                servers[side].url, headers, args.clients, per_client, f"{side}-{number}", args.get
            ),
        )
    per_round = per_client * args.clients
    cpu = {side: [seconds * 1000 / per_round for seconds, _ in rounds] for side, rounds in spent.items()}
    Mission.objects.filter(name__startswith=PREFIX).delete()
    what = "GET /robot" if args.get else "POST /mission"
    print(
        f"API CPU ms per {what}, {args.rounds} rounds of {per_client * args.clients} per side "
        f"({args.clients} clients), interleaved;"
    )
    print(f"calibration {calibration:.1f} ms (then {cpu_speed_ms():.1f})")
    for side, tree in (("a", args.a), ("b", args.b)):
        values = cpu[side]
        print(
            f"  {side} ({tree}): median {statistics.median(values):.3f}, "
            f"mean {statistics.mean(values):.3f}, min {min(values):.3f}, max {max(values):.3f}"
        )
    ratios = [a / b for a, b in zip(cpu["a"], cpu["b"], strict=True)]
    print(f"  a/b per round pair: median {statistics.median(ratios):.3f}")


if __name__ == "__main__":
    main()
