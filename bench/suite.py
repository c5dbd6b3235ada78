"""`make bench`: start a Mission Dispatch stack of its own, run the benchmark runs, write the report.

The stack uses its own database (`mission_dispatch_bench`), Redis server (port 6391), API port and Mosquitto
broker (`deploy/mosquitto/conf.d/tuning.conf`'s settings on port 1884), so it never mixes with `make run`; its
processes are those of `deploy/Procfile` (no simulator), with `--bridges`
bridges (sharing the robots' messages through an MQTT shared subscription) and `--workers` step-worker
processes. Step capacity follows step-worker processes (where the machine has the cores); a bridge adds
MQTT intake only. The `scale` suite once per layout into one directory, whose `latest.md` then compares them
(runs are labelled by layout; `mission-dispatch` alone is the Procfile's, one bridge and one worker);
`make bench` ends with this comparison of one and two workers (bench/results/layouts).

    .venv/bin/python -m bench.suite --suite scale --workers 1 --output bench/results/layouts
    .venv/bin/python -m bench.suite --suite scale --workers 2 --output bench/results/layouts

Every run reports the server's CPU per order (all the stack's processes: API, bridge, workers, beat, its
database's PostgreSQL backends, its Redis and its broker) beside throughput and latency, with the machine's
calibration at the run's start (bench/README.md, "The yardstick"). `--ab REF` compares another commit with
this tree: the suite's runs on REF's tree and on this one, alternately, each on a freshly started stack,
in `--pairs` interleaved pairs (A B, B A, A B, ...), and the median of the pairs' ratios:

    .venv/bin/python -m bench.suite --suite saturation --ab main --pairs 3
"""

from __future__ import annotations

import argparse
import json
import os
import re
import secrets
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import redis

from bench import fleet, measure, report
from bench.processes import running

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"  # make bench's results; their report is bench/latest.md
VENV_BIN = Path(sys.executable).parent
CELERY = str(VENV_BIN / "celery")
API_PORT = 5100
BROKER_PORT = 1884
REDIS_PORT = 6391  # a Redis server of the stack's own: its CPU is the stack's alone
DB_NAME = "mission_dispatch_bench"
BEAT_SCHEDULE = "/tmp/mission-dispatch-bench-beat"
BROKER_CONFIG = ROOT / "deploy" / "mosquitto" / "conf.d" / "tuning.conf"
# As in `deploy/Procfile`: on a machine it shares with the dispatch path (bridge, steps, PostgreSQL, broker),
# the API gets the CPU only after them, so a burst of requests never queues the steps behind it.
API_NICENESS = 5
# The stack's own key (the settings refuse the built-in development one); nothing outlives the stack.
SECRET_KEY = secrets.token_urlsafe(50)


def stack_env() -> dict[str, str]:
    """The stack's settings (the FLEET_ variables of the caller's environment are not passed on)."""
    return {
        "DJANGO_SETTINGS_MODULE": "fleet.settings",
        "FLEET_DB_NAME": DB_NAME,
        "FLEET_REDIS_URL": f"redis://127.0.0.1:{REDIS_PORT}/0",
        "FLEET_API_PORT": str(API_PORT),
        "FLEET_MQTT_PORT": str(BROKER_PORT),
        "FLEET_LOG_LEVEL": "WARNING",
        "FLEET_SECRET_KEY": SECRET_KEY,
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
    # The tests' (tests/bench/test_yardstick.py): a few seconds of five robots.
    "tiny": {
        "saturation-n5": [
            *["--nodes", "1", "--robots", "5", "--duration", "3", "--warmup", "1", "--sample-every", "3"],
            *["--settle-cores", "2"],  # the shared machine's other work must not hold the run up
        ]
    },
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
SUITES["realistic"] = {"realistic-n1000": SUITES["short"]["realistic-n1000"]}
# Missions without a robot (issue 41; bench/README.md "Assignment"): a burst of one mission per idle robot,
# and the realistic fleet at N=1000 with its missions unbound and, to compare, the same run named.
UNBOUND_N1000 = ["--unbound", "--nodes", "1", "--robots", "1000"]
SUITES["assignment"] = {
    "burst-n1000": [*UNBOUND_N1000, "--mode", "burst", "--duration", "10", "--warmup", "5"],
    "unbound-n1000": [*UNBOUND_N1000, *REALISTIC_N1000[4:], "--duration", "60", "--warmup", "20"],
    "named-n1000": SUITES["short"]["realistic-n1000"],
}
# The steady state alone, unbound then named on one stack: A/B pairs of a change to issue 41's ratio.
SUITES["steady"] = {name: SUITES["assignment"][name] for name in ("unbound-n1000", "named-n1000")}
SUITES["unbound"] = {"unbound-n1000": SUITES["assignment"]["unbound-n1000"]}
# The tests' (tests/bench/test_unbound.py): a few seconds of five robots and their missions without a robot.
SUITES["tiny-unbound"] = {
    "unbound-n5": [
        *["--unbound", "--nodes", "1", "--robots", "5", "--delay", "0.2", "--duration", "3", "--warmup", "1"],
        *["--sample-every", "3", "--settle-cores", "2"],
    ]
}
# The saturation runs alone, to compare layouts (--bridges, --workers).
SUITES["scale"] = {label: SUITES["full"][label] for label in ("saturation-n100", "saturation-n500")}


def client_args(tree: Path = ROOT) -> list[str]:
    """bench.fleet's options for this stack, its processes run from source tree `tree`: its API and
    broker, its process groups, its PostgreSQL database and Redis for the round-trip probe."""
    groups = [f"--proc={group}={pattern}" for group, pattern in process_groups(tree).items()]
    return [
        *["--base-url", f"http://127.0.0.1:{API_PORT}", "--mqtt-port", str(BROKER_PORT), *groups],
        *["--probe-postgres", f"host=127.0.0.1 user=postgres dbname={DB_NAME}"],
        *["--probe-redis", f"redis://127.0.0.1:{REDIS_PORT}/0"],
    ]


def process_groups(tree: Path = ROOT) -> dict[str, str]:
    """bench.fleet's process groups (command-line regexes) of the stack run from `tree`: its processes
    alone, whatever else the machine runs (a `make run`, tests' servers, other databases' backends).
    PostgreSQL is the backends (and autovacuum workers) of the stack's database; the postmaster and the
    server's shared processes (checkpointer, WAL writer, ...) serve every database and are not counted."""
    return {
        "api": rf"granian .*--port {API_PORT}\b",
        "bridge": rf"{re.escape(str(tree / 'manage.py'))} mqtt_bridge",
        "workers": r"celery .*\bworker\b.* -n bench-(?:steps|notify)\b",
        "beat": rf"celery .*\bbeat\b.*{re.escape(BEAT_SCHEDULE)}",
        "redis": rf"^redis-server \S*:{REDIS_PORT}\b",
        "postgres": rf"^postgres: .*\b{re.escape(DB_NAME)}\b",  # "postgres: 15/main: user db host(port) ..."
        "broker": rf"mosquitto .*-p {BROKER_PORT}\b",
    }


def services() -> dict[str, list[str]]:
    """The stack's broker and Redis server (this tree's broker configuration, whichever tree is measured)."""
    return {
        "broker": ["mosquitto", "-c", str(BROKER_CONFIG), "-p", str(BROKER_PORT)],
        "redis": [
            *["redis-server", "--port", str(REDIS_PORT), "--bind", "127.0.0.1"],
            *["--save", "", "--appendonly", "no"],  # in memory only, as the stack's data
        ],
    }


def processes(bridges: int = 1, workers: int = 1, tree: Path = ROOT) -> dict[str, list[str]]:
    """Name -> command line of the stack's server processes run from source tree `tree`: `deploy/Procfile`'s,
    with `bridges` bridges and `workers` step workers. Several bridges join a shared-subscription group unique
    to this stack, so another stack on the same broker never takes their messages."""
    share = ["--share-group", f"bench-{uuid.uuid4().hex[:8]}"] if bridges > 1 else []
    return {
        "api": api_command(API_PORT),
        **{
            # manage.py by its path: the tree's bridge tells itself apart from any other on the machine
            _numbered("bridge", i, bridges): [sys.executable, str(tree / "manage.py"), "mqtt_bridge", *share]
            for i in range(bridges)
        },
        **{
            _numbered("worker", i, workers): worker_command(
                "steps", f"bench-{_numbered('steps', i, workers)}", 12
            )
            for i in range(workers)
        },
        "notify": worker_command("notify", "bench-notify", 8),
        "beat": [CELERY, "-A", "fleet", "beat", "--schedule", BEAT_SCHEDULE],
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
def stack(logs: Path, *, bridges: int = 1, workers: int = 1, tree: Path = ROOT) -> Iterator[str]:
    """The benchmark's server processes, run from source tree `tree`, on a fresh database and a fresh Redis;
    yields an API token for the fleet's requests."""
    env = {key: value for key, value in os.environ.items() if not key.startswith("FLEET_")} | stack_env()
    # A server process gone (a crashed bridge, say) fails the run: its figures describe another layout.
    with running(services(), ROOT, env, logs):
        _wait_for_redis()
        # Every suite starts from an empty database: missions of earlier runs would slow the sweeps down.
        postgres = ["-h", "127.0.0.1", "-U", "postgres"]
        subprocess.run(["dropdb", "--if-exists", *postgres, DB_NAME], check=True)
        subprocess.run(["createdb", *postgres, DB_NAME], check=True)
        subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=tree, env=env, check=True)
        token = api_token_create(env, "bench", tree)
        with running(processes(bridges, workers, tree), tree, env, logs):
            _wait_for_api()
            yield token


def api_token_create(env: dict[str, str], name: str, tree: Path = ROOT) -> str:
    """A new API token in the database `env` names (`api_token create` prints it alone on its last line)."""
    done = subprocess.run(
        [sys.executable, "manage.py", "api_token", "create", name],
        cwd=tree,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return done.stdout.splitlines()[-1]


def _count(number: int, what: str) -> str:
    return f"{number} {what}" if number == 1 else f"{number} {what}s"


def _wait_for_redis(timeout: float = 10) -> None:
    client = redis.Redis(host="127.0.0.1", port=REDIS_PORT)
    deadline = time.monotonic() + timeout
    try:
        while True:
            try:
                client.ping()
                return
            except redis.ConnectionError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
    finally:
        client.close()


def _wait_for_api(timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{API_PORT}/health", timeout=2):
                return
        except OSError:
            time.sleep(0.5)
    raise RuntimeError("the benchmark stack's API did not come up")


def run_suite(suite: str, token: str, label: str, output: Path, tree: Path = ROOT, tag: str = "") -> dict:
    """The suite's runs against the stack run from `tree` (bench.fleet from this tree, whichever is
    measured); run name -> result, each also written to `output` and summed up on the console."""
    results = {}
    for name, run in SUITES[suite].items():
        print(f"--- {name}{tag}", flush=True)
        run_id = uuid.uuid4().hex[:6]
        common = ["--api-token", token, "--label", label, "--output", str(output), "--run-id", run_id]
        fleet.main([*client_args(tree), *common, *run])
        [path] = output.glob(f"*-{run_id}.json")
        results[name] = json.loads(path.read_text())
        print(f"=== {name}{tag}: {report.run_line(results[name])}", flush=True)
    return results


@contextmanager
def worktree(ref: str) -> Iterator[tuple[Path, str]]:
    """`ref` checked out (detached) in a temporary git worktree, removed at the end; yields its path and
    its commit's short hash."""
    commit = _git("rev-parse", "--verify", "--short", f"{ref}^{{commit}}")
    parent = Path(tempfile.mkdtemp(prefix="md-ab-"))
    path = parent / "tree"
    _git("worktree", "add", "--detach", str(path), commit)
    try:
        yield path, commit
    finally:
        _git("worktree", "remove", "--force", str(path))
        shutil.rmtree(parent, ignore_errors=True)


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True, text=True).stdout.strip()


def ab(ref: str, pairs: int, suite: str, output: Path, label: str, bridges: int, workers: int) -> int:
    """The suite on `ref`'s tree (side a) and on this one (side b) in `pairs` interleaved pairs, in
    `bench.measure.interleaved`'s order (a b, b a, a b, ...), each run on a stack started afresh from its
    side's tree (database and Redis emptied); writes `ab.json` and `ab.md` to `output` and prints the
    comparison."""
    head = _git("rev-parse", "--short", "HEAD")
    changed = " with uncommitted changes" if _git("status", "--porcelain", "--untracked-files=no") else ""
    output.mkdir(parents=True, exist_ok=True)
    with worktree(ref) as (ref_tree, ref_commit), autovacuum():
        trees = {"a": ref_tree, "b": ROOT}
        names = {"a": f"{ref} ({ref_commit})", "b": f"this tree ({head}{changed})"}
        if _procfile_names(ref_tree) != _procfile_names(ROOT):
            print(
                f"warning: {ref}'s deploy/Procfile has other processes ({sorted(_procfile_names(ref_tree))});"
                " both sides run this tree's command lines",
                flush=True,
            )
        order = list(measure.interleaved_order(["a", "b"], pairs))
        results: list[dict[str, dict]] = [{} for _ in range(pairs)]
        for number, side in order:
            tag = f" [pair {number + 1}, {side}: {names[side]}]"
            logs = output / "logs" / f"{side}{number + 1}"
            with stack(logs, bridges=bridges, workers=workers, tree=trees[side]) as token:
                results[number][side] = run_suite(suite, token, f"{label} {side}", output, trees[side], tag)
    comparison = report.ab_comparison(results, order, names)
    (output / "ab.json").write_text(json.dumps(comparison, indent=2) + "\n")
    markdown = report.ab_markdown(comparison)
    (output / "ab.md").write_text(markdown)
    print(markdown, flush=True)
    print(f"wrote {output / 'ab.md'} and ab.json", flush=True)
    return 0


def _procfile_names(tree: Path) -> set[str]:
    procfile = tree / "deploy" / "Procfile"
    lines = procfile.read_text().splitlines() if procfile.exists() else []
    return {line.split(":", 1)[0] for line in lines if ":" in line}


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
    parser.add_argument(
        "--ab",
        metavar="REF",
        help="compare commit REF (its tree, side a) with this tree (side b) in interleaved pairs; writes "
        "ab.md and ab.json (default directory: bench/results/ab-<time>)",
    )
    parser.add_argument("--pairs", type=int, default=3, help="with --ab: pairs of runs (a, b)")
    args = parser.parse_args(argv)
    if args.bridges < 1 or args.workers < 1:
        parser.error("--bridges and --workers must be at least 1")
    if args.pairs < 1:
        parser.error("--pairs must be at least 1")
    # Runs are labelled by layout, so one report can compare layouts; the Procfile's keeps the old label.
    label = "mission-dispatch"
    if (args.bridges, args.workers) != (1, 1):
        label += f" ({_count(args.bridges, 'bridge')}, {_count(args.workers, 'worker')})"
    if args.ab:
        output = args.output
        if output == RESULTS:
            output = RESULTS / time.strftime("ab-%Y%m%d-%H%M%S")
        return ab(args.ab, args.pairs, args.suite, output, label, args.bridges, args.workers)
    with autovacuum(), stack(args.output / "logs", bridges=args.bridges, workers=args.workers) as token:
        run_suite(args.suite, token, label, args.output)
    results = sorted(str(path) for path in args.output.glob("*.json"))
    report_dir = ROOT / "bench" if args.output.resolve() == RESULTS else args.output
    return report.main([*results, "--output", str(report_dir), "--name", "latest"])


if __name__ == "__main__":
    sys.exit(main())
