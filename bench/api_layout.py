"""A/B of the API's serving layouts: REST latency through real granian servers, alternating.

- `wsgi`: the API as granian's WSGI interface (fleet.wsgi, 2 workers x 4 blocking threads) and the streams
  on a process of their own (fleet.asgi on another port): the layout before the streams moved to :5000.
- `asgi`: one granian ASGI process (fleet.asgi, 2 workers x FLEET_API_THREADS=4 REST threads) serving the
  REST API and the streams on one port (deploy/Procfile).

Each run: a sequential loop of GET /robot?names=... (10 of the bench's robots) and POST /mission, then the
same from 8 concurrent clients; with `--streams K`, K server-sent event streams of the missions are open
and read meanwhile (each POST /mission is an event on every one of them). Run on a database of its
own (it creates robots and missions and deletes them) and a Redis database of its own (its missions' step
requests wait there: no worker runs), with nothing else competing for the CPU:

    FLEET_DB_NAME=mission_dispatch_bench FLEET_REDIS_URL=redis://127.0.0.1:6379/3 \
        .venv/bin/python -m bench.api_layout --pairs 4 --streams 50

Results and the machine's calibration figure: bench/HISTORY.md, "One port for the API and the streams".
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import django
import requests

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

from access.services import api_token_create  # noqa: E402
from bench.measure import CALIBRATION_ITERATIONS, _calibration_work, latency_summary  # noqa: E402
from bench.processes import running  # noqa: E402
from bench.suite import api_command, granian  # noqa: E402
from changes.models import Change  # noqa: E402
from missions.models import Mission  # noqa: E402
from robots.models import Robot  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PREFIX = "layout-ab-"
CONCURRENCY = 8


def _wsgi_api(port: int) -> list[str]:
    """The API as deploy/Procfile ran it before the streams came to its port."""
    options = ["--interface", "wsgi", "--workers", "2", "--blocking-threads", "4"]
    return granian(port, "fleet.wsgi:application", *options)


def _stream_process(port: int) -> list[str]:
    """The stream process deploy/Procfile ran beside it (fleet.asgi, one worker)."""
    return granian(port, "fleet.asgi:application", "--interface", "asginl", "--workers", "1")


LAYOUTS: dict[str, list[Callable[[int], list[str]]]] = {  # the first process is the API
    "wsgi": [_wsgi_api, _stream_process],
    "asgi": [api_command],  # deploy/Procfile's
}


@dataclass
class Run:
    layout: str
    sequential: dict[str, list[float]] = field(default_factory=lambda: {"get": [], "post": []})
    concurrent: dict[str, list[float]] = field(default_factory=lambda: {"get": [], "post": []})
    concurrent_seconds: float = 0.0
    events: int = 0


def free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class Server(NamedTuple):
    url: str
    pid: int  # also its process group's: the server's workers are in it


@contextmanager
def served(
    command_for: Callable[[int], list[str]], env: dict[str, str], log: Path, *, cwd: Path = ROOT
) -> Iterator[Server]:
    """The server `command_for(port)` starts from source tree `cwd` (`bench.processes.running`, its
    output in `log`) on a free port, once it answers GET /health; stopped, with its workers, at the end."""
    port = free_port()
    command = command_for(port)
    url = f"http://127.0.0.1:{port}"
    with running({log.stem: command}, cwd, env, log.parent) as started:
        process = started[log.stem]
        deadline = time.monotonic() + 60
        while True:
            try:
                if requests.get(f"{url}/health", timeout=5).ok:
                    break
            except requests.ConnectionError:
                pass
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"{command} did not start; see {log}")
            time.sleep(0.1)
        yield Server(url, process.pid)


def _stream_reader(url: str, headers: dict[str, str], counted: list[int], stop: threading.Event) -> None:
    """One SSE client of the bench's missions: counts the events it reads until `stop`."""
    with requests.get(url, headers=headers, stream=True, timeout=(10, 60)) as response:
        response.raise_for_status()
        for line in response.iter_lines():
            if line.startswith(b"event: mission"):
                counted[0] += 1
            if stop.is_set():
                return


def _loop(
    session: requests.Session, api: str, headers: dict[str, str], robots: list[str], count: int, tag: str
) -> dict[str, list[float]]:
    """`count` GET /robot and `count` POST /mission, alternating; each one's latency in seconds."""
    names = "&".join(f"names={name}" for name in robots[:10])
    tree = [{"name": "go", "route": {"waypoints": [{"x": 1, "y": 1}]}}]
    latencies: dict[str, list[float]] = {"get": [], "post": []}
    for i in range(count):
        started = time.perf_counter()
        response = session.get(f"{api}/robot?{names}", headers=headers, timeout=30)
        latencies["get"].append(time.perf_counter() - started)
        response.raise_for_status()
        body = {"robot": robots[i % len(robots)], "name": f"{PREFIX}{tag}-{i}", "mission_tree": tree}
        started = time.perf_counter()
        response = session.post(f"{api}/mission", json=body, headers=headers, timeout=30)
        latencies["post"].append(time.perf_counter() - started)
        response.raise_for_status()
    return latencies


def _measure(
    layout: str, env: dict[str, str], args: argparse.Namespace, token: str, tag: str, logs: Path
) -> Run:
    run = Run(layout)
    _clean(robots=False)  # every run's streams start with the same snapshot
    headers = {"Authorization": f"Bearer {token}"}
    robots = [f"{PREFIX}{i}" for i in range(args.robots)]
    with ExitStack() as stack:
        urls = [
            stack.enter_context(served(command_for, env, logs / f"{layout}-{n}.log")).url
            for n, command_for in enumerate(LAYOUTS[layout])
        ]
        api, streams = urls[0], urls[-1]
        stop, counted = threading.Event(), [0]
        readers = [
            threading.Thread(
                target=_stream_reader,
                args=(f"{streams}/events?kind=mission", headers, counted, stop),
                daemon=True,
            )
            for _ in range(args.streams)
        ]
        for reader in readers:
            reader.start()
        with requests.Session() as session:
            _loop(session, api, headers, robots, args.warmup, f"{tag}-warm")
            run.sequential = _loop(session, api, headers, robots, args.requests, f"{tag}-seq")

        def client(number: int) -> dict[str, list[float]]:
            with requests.Session() as session:
                return _loop(session, api, headers, robots, args.requests // CONCURRENCY, f"{tag}-c{number}")

        started = time.perf_counter()
        with ThreadPoolExecutor(CONCURRENCY) as pool:
            for latencies in pool.map(client, range(CONCURRENCY)):
                for kind in ("get", "post"):
                    run.concurrent[kind] += latencies[kind]
        run.concurrent_seconds = time.perf_counter() - started
        stop.set()
        run.events = counted[0]
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=4, help="runs of each layout, alternating")
    parser.add_argument("--requests", type=int, default=400, help="GETs and POSTs per loop")
    parser.add_argument("--warmup", type=int, default=50)
    parser.add_argument("--robots", type=int, default=100)
    parser.add_argument("--streams", type=int, default=0, help="open SSE streams read during each run")
    parser.add_argument("--logs", type=Path, default=Path("/tmp/api-layout-logs"))
    args = parser.parse_args()
    args.logs.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    _calibration_work(CALIBRATION_ITERATIONS)
    calibration_ms = (time.perf_counter() - started) * 1000
    _clean()
    Robot.objects.bulk_create(
        [Robot(name=f"{PREFIX}{i}", serial_number=f"{PREFIX}{i}") for i in range(args.robots)]
    )
    _, token = api_token_create(name=f"{PREFIX}{os.getpid()}")
    env = {**os.environ, "FLEET_API_THREADS": "4", "PYTHONUNBUFFERED": "1"}
    runs: list[Run] = []
    try:
        for pair in range(args.pairs):
            order = ["wsgi", "asgi"] if pair % 2 == 0 else ["asgi", "wsgi"]
            for layout in order:
                runs.append(_measure(layout, env, args, token, f"{pair}{layout}", args.logs))
                print(f"pair {pair} {layout}: {_row(runs[-1])}", flush=True)
    finally:
        _clean()
    print(f"\ncalibration work: {calibration_ms:.1f} ms (lower is faster); {args.streams} open streams")
    print(
        "| layout | GET /robot p50 / p99 (ms) | POST /mission p50 / p99 (ms) "
        "| 8 clients: GET p50 / POST p50 (ms), requests/s | events read |"
    )
    print("|---|---|---|---|---|")
    for layout in LAYOUTS:
        mine = [run for run in runs if run.layout == layout]
        print(f"| {layout} (all runs) | {_row_of(mine)} |")


def _row(run: Run) -> str:
    return _row_of([run])


def _row_of(runs: list[Run]) -> str:
    def pooled(pick: Callable[[Run], list[float]]) -> dict:
        return latency_summary([sample for run in runs for sample in pick(run)])

    get, post = pooled(lambda run: run.sequential["get"]), pooled(lambda run: run.sequential["post"])
    cget, cpost = pooled(lambda run: run.concurrent["get"]), pooled(lambda run: run.concurrent["post"])
    rate = statistics.mean(
        (len(run.concurrent["get"]) + len(run.concurrent["post"])) / run.concurrent_seconds for run in runs
    )
    return (
        f"{get['p50']} / {get['p99']} | {post['p50']} / {post['p99']} | "
        f"{cget['p50']} / {cpost['p50']}, {rate:.0f} | {sum(run.events for run in runs)}"
    )


def _clean(*, robots: bool = True) -> None:
    """The bench's missions (and robots), and the change feed's rows of them."""
    Mission.objects.filter(name__startswith=PREFIX).delete()
    if robots:
        Robot.objects.filter(name__startswith=PREFIX).delete()
    Change.objects.filter(name__startswith=PREFIX).delete()


if __name__ == "__main__":
    main()
