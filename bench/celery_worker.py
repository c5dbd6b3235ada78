"""Celery's own CPU per task in a step worker, by configuration: pool, concurrency, prefetch multiplier.

One worker per configuration (`celery -A fleet worker` with the project's settings, as `deploy/Procfile`
runs the step worker, but on a queue of its own) runs at once; rounds of tasks go to one worker, then the
next, in turn, and each round's CPU of that worker (from /proc) is divided by its tasks. Each task only
waits, without CPU, as a step waits for PostgreSQL and Redis (`--wait-ms`), then counts itself done: what
the worker spends is Celery's receiving, decoding, hand-off to the pool, tracing and acknowledging, and
the round's wall time shows how well the configuration overlaps the waits. With `--b`, every configuration
also runs from another source tree (e.g. `git archive <rev> | tar -x -C /tmp/md-base` with a link to this
`.venv`), in the same turns. Run with nothing else running:

    FLEET_SECRET_KEY=... FLEET_REDIS_URL=redis://127.0.0.1:6379/4 .venv/bin/python -m bench.celery_worker

Results and the machine's calibration figure: bench/HISTORY.md.
"""

from __future__ import annotations

import argparse
import os
import shlex
import statistics
import sys
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

from bench.celery_tasks import WAIT_TASK  # noqa: E402
from bench.measure import CpuMeter, cpu_speed_ms, interleaved  # noqa: E402
from bench.processes import running  # noqa: E402
from bench.suite import CELERY  # noqa: E402
from fleet.celery import app  # noqa: E402
from robots import livestate  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
# The step worker of deploy/Procfile first (its prefetch multiplier is the settings' default, 1); then what it
# was chosen against.
CONFIGURATIONS = {
    "threads-12-prefetch-1": "--pool threads --concurrency 12 --prefetch-multiplier 1",
    "threads-12-prefetch-4": "--pool threads --concurrency 12 --prefetch-multiplier 4",
    "threads-12-prefetch-16": "--pool threads --concurrency 12 --prefetch-multiplier 16",
    "threads-4-prefetch-4": "--pool threads --concurrency 4 --prefetch-multiplier 4",
    "solo-prefetch-4": "--pool solo --prefetch-multiplier 4",
}


def worker_command(queue: str, options: str) -> list[str]:
    return [
        CELERY, "-A", "fleet", "worker", "-Q", queue, *shlex.split(options),
        "--without-gossip", "--without-mingle", "-n", f"{queue}@%h", "-I", "bench.celery_tasks",
    ]  # fmt: skip


@contextmanager
def worker(queue: str, options: str, logs: Path, tree: Path = ROOT) -> Iterator[None]:
    """A worker of `queue` with `options`, run from source tree `tree`, stopped (its queue deleted) at the
    end; its output in `logs/<queue>.log`."""
    with running({queue: worker_command(queue, options)}, tree, os.environ, logs):
        yield
    app.connection_for_write().default_channel.queue_delete(queue)


def task_round(queue: str, tasks: int, wait_ms: float, timeout: float = 120) -> None:
    """Send `tasks` tasks to `queue` at once and wait until all are done."""
    counter = f"bench:celery-worker:{queue}"
    redis = livestate.client()
    redis.delete(counter)
    began = time.monotonic()
    with app.producer_or_acquire() as producer:
        for _ in range(tasks):
            app.send_task(WAIT_TASK, (counter, wait_ms), queue=queue, producer=producer)
    while int(redis.get(counter) or 0) < tasks:
        if time.monotonic() - began > timeout:
            raise RuntimeError(f"{queue}: {redis.get(counter)} of {tasks} tasks done in {timeout} s")
        time.sleep(0.005)
    redis.delete(counter)


def measure(
    configurations: dict[str, tuple[str, Path]], rounds: int, tasks: int, wait_ms: float, logs: Path
) -> dict[str, dict[str, list[float]]]:
    """Per configuration (name -> worker options, source tree), per round: CPU ms per task and wall ms per
    task (rounds interleaved)."""
    run = uuid.uuid4().hex[:8]
    queues = {name: f"bench-{run}-{index}" for index, name in enumerate(configurations)}
    meter = CpuMeter({name: rf"-Q {queue} " for name, queue in queues.items()})
    with ExitStack() as stack:
        for name, (options, tree) in configurations.items():
            stack.enter_context(worker(queues[name], options, logs, tree))
        for name in configurations:  # up, and past its first tasks
            task_round(queues[name], tasks, wait_ms, timeout=120)
        spent = interleaved(
            list(configurations), rounds, meter, lambda name, _: task_round(queues[name], tasks, wait_ms)
        )
    return {
        name: {
            "cpu": [cpu * 1000 / tasks for cpu, _ in each],
            "wall": [wall * 1000 / tasks for _, wall in each],
        }
        for name, each in spent.items()
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=10, help="rounds per configuration, in turn")
    parser.add_argument("--tasks", type=int, default=1000, help="tasks per round")
    parser.add_argument("--wait-ms", type=float, default=2.0, help="each task's wait without CPU")
    parser.add_argument(
        "--config", action="append", metavar="NAME=OPTIONS",
        help="a configuration (worker options); replaces the built-in ones; the first is the baseline",
    )  # fmt: skip
    parser.add_argument("--b", type=Path, help="another source tree to run every configuration from too")
    parser.add_argument("--logs", type=Path, default=Path("/tmp/celery-worker-logs"))
    args = parser.parse_args(argv)
    chosen = dict(c.split("=", 1) for c in args.config) if args.config else CONFIGURATIONS
    configurations = {name: (options, ROOT) for name, options in chosen.items()}
    if args.b:
        b = args.b.resolve()
        configurations |= {f"{name} ({args.b})": (options, b) for name, options in chosen.items()}
    args.logs.mkdir(parents=True, exist_ok=True)
    calibration = cpu_speed_ms()
    figures = measure(configurations, args.rounds, args.tasks, args.wait_ms, args.logs)
    print(
        f"Celery step worker, {args.rounds} rounds of {args.tasks} tasks per configuration (each waits "
        f"{args.wait_ms} ms), interleaved; calibration {calibration:.1f} ms (then {cpu_speed_ms():.1f})"
    )
    print("| configuration | CPU ms per task | against the first | wall ms per task |")
    print("|---|---|---|---|")
    baseline = figures[next(iter(configurations))]["cpu"]
    for name, values in figures.items():
        ratio = statistics.median(a / b for a, b in zip(values["cpu"], baseline, strict=True))
        print(
            f"| {name} | {statistics.median(values['cpu']):.3f} | {ratio:.3f} "
            f"| {statistics.median(values['wall']):.3f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
