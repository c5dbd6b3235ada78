"""`make bench`: start a Mission Dispatch stack of its own, run the benchmark runs, write the report.

The stack uses its own database (`mission_dispatch_bench`), Redis database and API port, so it never
mixes with `make run`; its processes are those of `deploy/Procfile` (no simulator).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from bench import fleet, report

ROOT = Path(__file__).resolve().parent.parent
VENV_BIN = Path(sys.executable).parent
API_PORT = 5100
STACK_ENV = {
    "FLEET_DB_NAME": "mission_dispatch_bench",
    "FLEET_REDIS_URL": "redis://127.0.0.1:6379/3",
    "FLEET_API_PORT": str(API_PORT),
    "FLEET_LOG_LEVEL": "WARNING",
}
PROCESSES = {
    "api": [
        str(VENV_BIN / "gunicorn"),
        "fleet.wsgi",
        "--bind",
        f"127.0.0.1:{API_PORT}",
        "--workers",
        "2",
        "--threads",
        "4",
        "--no-control-socket",
    ],
    "bridge": [sys.executable, "manage.py", "mqtt_bridge"],
    "worker": [
        str(VENV_BIN / "celery"),
        "-A",
        "fleet",
        "worker",
        "-Q",
        "steps",
        "--pool",
        "threads",
        "--concurrency",
        "4",
        "--without-gossip",
        "--without-mingle",
        "-n",
        "bench-steps@%h",
    ],
    "notify": [
        str(VENV_BIN / "celery"),
        "-A",
        "fleet",
        "worker",
        "-Q",
        "notify",
        "--pool",
        "threads",
        "--concurrency",
        "4",
        "--without-gossip",
        "--without-mingle",
        "-n",
        "bench-notify@%h",
    ],
    "beat": [
        str(VENV_BIN / "celery"),
        "-A",
        "fleet",
        "beat",
        "--schedule",
        "/tmp/mission-dispatch-bench-beat",
    ],
}
# name -> bench.fleet arguments; "quick" is what CI can afford, "full" what bench/README.md reports.
# As in the comparison with the reference: one route node per mission, queue depth 2, 1 Hz state.
SUITES = {
    "quick": {"saturation-n10": ["--nodes", "1", "--robots", "10", "--duration", "10", "--warmup", "3"]},
    "full": {
        # Idle first: after a saturated run a stack is still working off its backlog.
        "idle-n2000": ["--mode", "idle", "--robots", "2000", "--duration", "60", "--warmup", "60"],
        "saturation-n100": ["--nodes", "1", "--robots", "100", "--duration", "60", "--warmup", "10"],
        "saturation-n500": ["--nodes", "1", "--robots", "500", "--duration", "60", "--warmup", "20"],
        "realistic-n1000": [
            "--nodes",
            "1",
            "--robots",
            "1000",
            "--delay",
            "5",
            "--duration",
            "300",
            "--warmup",
            "30",
        ],
        "realistic-n2000": [
            "--nodes",
            "1",
            "--robots",
            "2000",
            "--delay",
            "10",
            "--duration",
            "300",
            "--warmup",
            "40",
        ],
    },
}
SUITES["idle"] = {"idle-n2000": SUITES["full"]["idle-n2000"]}


@contextmanager
def stack(logs: Path) -> Iterator[None]:
    env = {**os.environ, **STACK_ENV}
    # Every suite starts from an empty database: missions of earlier runs would slow the sweeps down.
    subprocess.run(
        ["dropdb", "--if-exists", "-h", "127.0.0.1", "-U", "postgres", STACK_ENV["FLEET_DB_NAME"]], check=True
    )
    subprocess.run([sys.executable, "deploy/ensure_database.py"], cwd=ROOT, env=env, check=True)
    subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env, check=True)
    subprocess.run(["redis-cli", "-n", "3", "flushdb"], check=True, capture_output=True)
    logs.mkdir(parents=True, exist_ok=True)
    running = [
        subprocess.Popen(
            argv, cwd=ROOT, env=env, stdout=(logs / f"{name}.log").open("wb"), stderr=subprocess.STDOUT
        )
        for name, argv in PROCESSES.items()
    ]
    try:
        _wait_for_api()
        yield
    finally:
        for process in running:
            process.terminate()
        for process in running:
            process.wait(timeout=60)


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
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--suite", choices=sorted(SUITES), default="full")
    parser.add_argument("--output", type=Path, default=ROOT / "bench" / "results")
    args = parser.parse_args(argv)
    with stack(args.output / "logs"):
        for label, run in SUITES[args.suite].items():
            print(f"--- {label}", flush=True)
            fleet.main(
                [
                    "--base-url",
                    f"http://127.0.0.1:{API_PORT}",
                    "--label",
                    "mission-dispatch",
                    "--output",
                    str(args.output),
                    *run,
                ]
            )
    results = sorted(str(path) for path in args.output.glob("*.json"))
    return report.main([*results, "--output", str(ROOT / "bench"), "--name", "latest"])


if __name__ == "__main__":
    sys.exit(main())
