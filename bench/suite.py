"""`make bench`: start a Mission Dispatch stack of its own, run the benchmark runs, write the report.

The stack uses its own database (`mission_dispatch_bench`), Redis database, API port and Mosquitto broker
(`deploy/mosquitto/conf.d/tuning.conf`'s settings on port 1884), so it never mixes with `make run`; its
processes are those of `deploy/Procfile` (no simulator), with `--bridges`
bridges (sharing the robots' messages through an MQTT shared subscription) and `--workers` step-worker
processes. Step capacity follows step-worker processes (where the machine has the cores); a bridge adds
MQTT intake only. The `scale` suite once per layout into one directory, whose `latest.md` then compares them
(runs are labelled by layout; `mission-dispatch` alone is the Procfile's, one bridge and one worker);
`make bench` ends with this comparison of one and two workers (bench/results/layouts).

    .venv/bin/python -m bench.suite --suite scale --workers 1 --output bench/results/layouts
    .venv/bin/python -m bench.suite --suite scale --workers 2 --output bench/results/layouts
"""

from __future__ import annotations

import argparse
import os
import secrets
import subprocess
import sys
import time
import urllib.request
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import redis

from bench import fleet, report
from bench.processes import running

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"  # make bench's results; their report is bench/latest.md
VENV_BIN = Path(sys.executable).parent
CELERY = str(VENV_BIN / "celery")
API_PORT = 5100
BROKER_PORT = 1884
BROKER_CONFIG = ROOT / "deploy" / "mosquitto" / "conf.d" / "tuning.conf"
# As in `deploy/Procfile`: on a machine it shares with the dispatch path (bridge, steps, PostgreSQL, broker),
# the API gets the CPU only after them, so a burst of requests never queues the steps behind it.
API_NICENESS = 5
STACK_ENV = {
    "FLEET_DB_NAME": "mission_dispatch_bench",
    "FLEET_REDIS_URL": "redis://127.0.0.1:6379/3",
    "FLEET_API_PORT": str(API_PORT),
    "FLEET_MQTT_PORT": str(BROKER_PORT),
    "FLEET_LOG_LEVEL": "WARNING",
    # The stack's own key (the settings refuse the built-in development one); nothing outlives the stack.
    "FLEET_SECRET_KEY": secrets.token_urlsafe(50),
}
# The fleets the suites run (bench.fleet arguments without the measurement window). As in the issue's
# comparison with the reference: one route node per mission, queue depth 2, 1 Hz state. The realistic
# runs' start phase posts at the rate robots finish orders (N / delay), as robots fall idle in a working
# fleet.
SATURATION_N100 = ["--nodes", "1", "--robots", "100"]
REALISTIC_N1000 = ["--nodes", "1", "--robots", "1000", "--delay", "5", "--start-rate", "200"]
REALISTIC_N2000 = ["--nodes", "1", "--robots", "2000", "--delay", "10", "--start-rate", "200"]
# name -> bench.fleet arguments; "quick" is what CI can afford, "full" what bench/README.md reports.
SUITES = {
    "quick": {"saturation-n10": ["--nodes", "1", "--robots", "10", "--duration", "10", "--warmup", "3"]},
    "full": {
        # Idle first: after a saturated run a stack is still working off its backlog.
        "idle-n2000": ["--mode", "idle", "--robots", "2000", "--duration", "60", "--warmup", "60"],
        "saturation-n100": [*SATURATION_N100, "--duration", "60", "--warmup", "10"],
        "saturation-n500": ["--nodes", "1", "--robots", "500", "--duration", "60", "--warmup", "20"],
        # 30 minutes in 1-minute slices: latency flat over any 5 minutes, and memory flat over 30.
        "realistic-n1000": [*REALISTIC_N1000, "--duration", "1800", "--warmup", "30", "--sample-every", "60"],
        "realistic-n2000": [*REALISTIC_N2000, "--duration", "300", "--warmup", "40"],
    },
}
SUITES["idle"] = {"idle-n2000": SUITES["full"]["idle-n2000"]}
# A few minutes' look at the headline figures while working on them: the full suite's runs, shorter.
SUITES["short"] = {
    "saturation-n100": [*SATURATION_N100, "--duration", "30", "--warmup", "10"],
    "realistic-n1000": [*REALISTIC_N1000, "--duration", "60", "--warmup", "20"],
}
# N=2000's realistic fleet alone, shorter, in 30-s slices: its start and its steady state.
SUITES["n2000"] = {
    "realistic-n2000": [*REALISTIC_N2000, "--duration", "120", "--warmup", "40", "--sample-every", "30"]
}
# Saturation at N=100 alone, for A/B pairs of a change to the CPU per order (bench/README.md).
SUITES["saturation"] = {"saturation-n100": SUITES["short"]["saturation-n100"]}
# The saturation runs alone, to compare layouts (--bridges, --workers).
SUITES["scale"] = {label: SUITES["full"][label] for label in ("saturation-n100", "saturation-n500")}


# bench.fleet's options for this stack: its API and broker (the machine's own broker is not measured).
CLIENT_ARGS = [
    "--base-url",
    f"http://127.0.0.1:{API_PORT}",
    "--mqtt-port",
    str(BROKER_PORT),
    "--proc",
    f"broker=mosquitto .*-p {BROKER_PORT}",
]


def processes(bridges: int = 1, workers: int = 1) -> dict[str, list[str]]:
    """Name -> command line of the stack's processes: `deploy/Procfile`'s, with `bridges` bridges and
    `workers` step workers. Several bridges join a shared-subscription group unique to this stack, so
    another stack on the same broker never takes their messages."""
    share = ["--share-group", f"bench-{uuid.uuid4().hex[:8]}"] if bridges > 1 else []
    return {
        "broker": ["mosquitto", "-c", str(BROKER_CONFIG), "-p", str(BROKER_PORT)],
        "api": api_command(API_PORT),
        **{
            _numbered("bridge", i, bridges): [sys.executable, "manage.py", "mqtt_bridge", *share]
            for i in range(bridges)
        },
        **{
            _numbered("worker", i, workers): worker_command(
                "steps", f"bench-{_numbered('steps', i, workers)}", 12
            )
            for i in range(workers)
        },
        "notify": worker_command("notify", "bench-notify", 8),
        "beat": [CELERY, "-A", "fleet", "beat", "--schedule", "/tmp/mission-dispatch-bench-beat"],
    }


def api_command(port: int, workers: int = 2, *, access_log: bool = False) -> list[str]:
    """The API as `deploy/Procfile` runs it (its access log only if asked for), on `port` of this host."""
    options = ["--interface", "asginl", "--workers", str(workers), "--backpressure", "2048"]
    return granian(port, "fleet.asgi:application", *options, *(["--access-log"] if access_log else []))


def granian(port: int, app: str, *options: str) -> list[str]:
    """granian serving `app` on `port` of this host as deploy/Procfile serves the API (its niceness, a
    failed worker respawned, no websockets), with `options`."""
    address = ["--host", "127.0.0.1", "--port", str(port)]
    niceness = ["nice", "-n", str(API_NICENESS)]
    return [
        *niceness,
        str(VENV_BIN / "granian"),
        *address,
        *options,
        "--no-ws",
        "--respawn-failed-workers",
        app,
    ]


def _numbered(name: str, index: int, count: int) -> str:
    """`name` for a single process (as in `deploy/Procfile`), `name-1`, `name-2`, ... for several."""
    return name if count == 1 else f"{name}-{index + 1}"


def worker_command(queue: str, node: str, threads: int) -> list[str]:
    """A Celery worker of `queue` on `threads` threads, named `node` on this host (as `deploy/Procfile`)."""
    return [
        CELERY,
        "-A",
        "fleet",
        "worker",
        "-Q",
        queue,
        "--pool",
        "threads",
        "--concurrency",
        str(threads),
        "--without-gossip",
        "--without-mingle",
        "-n",
        f"{node}@%h",
    ]


@contextmanager
def autovacuum() -> Iterator[None]:
    """PostgreSQL's autovacuum on while the stack runs, as in any production database (it is the default;
    a CI machine's server may have it off). Without it the churning missions table measures its own bloat.
    """
    if _psql("SHOW autovacuum") == "on":
        yield
        return
    _psql("ALTER SYSTEM SET autovacuum = on")
    _psql("SELECT pg_reload_conf()")
    try:
        yield
    finally:
        _psql("ALTER SYSTEM RESET autovacuum")  # back to what the server's configuration files say
        _psql("SELECT pg_reload_conf()")


def _psql(command: str) -> str:
    argv = ["psql", "-h", "127.0.0.1", "-U", "postgres", "-d", "postgres", "-Atc", command]
    return subprocess.run(argv, check=True, capture_output=True, text=True).stdout.strip()


@contextmanager
def stack(logs: Path, *, bridges: int = 1, workers: int = 1) -> Iterator[str]:
    """The benchmark's server processes on a fresh database; yields an API token for the fleet's requests."""
    env = {**os.environ, **STACK_ENV}
    # Every suite starts from an empty database: missions of earlier runs would slow the sweeps down.
    subprocess.run(
        ["dropdb", "--if-exists", "-h", "127.0.0.1", "-U", "postgres", STACK_ENV["FLEET_DB_NAME"]], check=True
    )
    subprocess.run([sys.executable, "deploy/ensure_database.py"], cwd=ROOT, env=env, check=True)
    subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env, check=True)
    token = api_token_create(env, "bench")
    redis.Redis.from_url(STACK_ENV["FLEET_REDIS_URL"]).flushdb()
    # A server process gone (a crashed bridge, say) fails the run: its figures describe another layout.
    with running(processes(bridges, workers), ROOT, env, logs):
        _wait_for_api()
        yield token


def api_token_create(env: dict[str, str], name: str) -> str:
    """A new API token in the database `env` names (`api_token create` prints it alone on its last line)."""
    done = subprocess.run(
        [sys.executable, "manage.py", "api_token", "create", name],
        cwd=ROOT,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return done.stdout.splitlines()[-1]


def _count(number: int, what: str) -> str:
    return f"{number} {what}" if number == 1 else f"{number} {what}s"


def _wait_for_api(timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{API_PORT}/health", timeout=2):
                return
        except OSError:
            time.sleep(0.5)
    raise RuntimeError("the benchmark stack's API did not come up")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--suite", choices=sorted(SUITES), default="full")
    parser.add_argument(
        "--output",
        type=Path,
        default=RESULTS,
        help="directory for the runs' results and, unless it is the default, their latest.md and .png",
    )
    parser.add_argument("--bridges", type=int, default=1, help="bridge processes (one shared subscription)")
    parser.add_argument("--workers", type=int, default=1, help="step-worker processes (12 threads each)")
    args = parser.parse_args(argv)
    if args.bridges < 1 or args.workers < 1:
        parser.error("--bridges and --workers must be at least 1")
    # Runs are labelled by layout, so one report can compare layouts; the Procfile's keeps the old label.
    label = "mission-dispatch"
    if (args.bridges, args.workers) != (1, 1):
        label += f" ({_count(args.bridges, 'bridge')}, {_count(args.workers, 'worker')})"
    with autovacuum(), stack(args.output / "logs", bridges=args.bridges, workers=args.workers) as token:
        for name, run in SUITES[args.suite].items():
            print(f"--- {name}", flush=True)
            fleet.main(
                [
                    *CLIENT_ARGS,
                    "--api-token",
                    token,
                    "--label",
                    label,
                    "--output",
                    str(args.output),
                    *run,
                ]
            )
    results = sorted(str(path) for path in args.output.glob("*.json"))
    report_dir = ROOT / "bench" if args.output.resolve() == RESULTS else args.output
    return report.main([*results, "--output", str(report_dir), "--name", "latest"])


if __name__ == "__main__":
    sys.exit(main())
