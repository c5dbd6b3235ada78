"""What a run measures besides messages: latency summaries, CPU and memory of processes, the machine."""

from __future__ import annotations

import json
import math
import os
import platform
import re
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
PAGE_SIZE = os.sysconf("SC_PAGE_SIZE")
PROC = Path("/proc")

# Server process groups by command-line pattern (a regex searched in the command line).
DEFAULT_PROCESS_GROUPS = {
    "api": r"granian|gunicorn|manage\.py runserver|uvicorn",
    "bridge": r"mqtt_bridge",
    "workers": r"celery.*\bworker\b",
    "beat": r"celery.*\bbeat\b",
    "redis": r"redis-server",
    "postgres": r"^postgres|/postgres\b",
    "broker": r"mosquitto",
}
GENERATOR = "generator"
CALIBRATION_ITERATIONS = 5000  # about 150 ms of CPU on a 2.5 GHz core
CALIBRATION_REPEATS = 5
# The reference hour's calibration (ms): a figure of CPU per order scales to it as figure * 134 / cal, the
# CPU per order it would have taken on the machine as fast as then (a slower machine, cal above 134, scales
# down).
REFERENCE_CAL_MS = 134.0
ROUND_TRIPS = 500  # per probe and repeat: SELECT 1 on PostgreSQL, PING on Redis
ROUND_TRIP_REPEATS = 3


def latency_summary(samples: Sequence[float]) -> dict[str, float | int | None]:
    """count, mean, p50, p95, p99 and max in milliseconds, from samples in seconds (nearest rank)."""
    if not samples:
        return {"count": 0, "mean": None, "p50": None, "p95": None, "p99": None, "max": None}
    ordered = sorted(samples)

    def percentile(p: float) -> float:
        return round(ordered[max(0, math.ceil(p / 100 * len(ordered)) - 1)] * 1000, 2)

    return {
        "count": len(ordered),
        "mean": round(sum(ordered) / len(ordered) * 1000, 2),
        "p50": percentile(50),
        "p95": percentile(95),
        "p99": percentile(99),
        "max": round(ordered[-1] * 1000, 2),
    }


@dataclass(frozen=True)
class ProcessSample:
    cpu_seconds: float  # user + system, plus that of children it has reaped (postgres backends, workers)
    rss_bytes: int
    parent: int = 0  # its parent's pid; 0: unknown


def process_sample(pid: int) -> ProcessSample | None:
    """From /proc/<pid>/stat; None if the process is gone."""
    try:
        text = (PROC / str(pid) / "stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2 :].split()  # after "pid (comm) "; comm may contain spaces
    utime, stime, cutime, cstime = (int(value) for value in fields[11:15])
    cpu_seconds = (utime + stime + cutime + cstime) / CLOCK_TICKS
    return ProcessSample(cpu_seconds, int(fields[21]) * PAGE_SIZE, int(fields[1]))


def command_lines() -> dict[int, str]:
    lines = {}
    for entry in PROC.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            raw = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if raw:
            lines[int(entry.name)] = raw.rstrip(b"\0").replace(b"\0", b" ").decode(errors="replace")
    return lines


@dataclass(frozen=True)
class Snapshot:
    """Which processes each group had at one moment, and their counters then."""

    members: dict[str, list[int]]
    samples: dict[int, ProcessSample]
    cpu_times: tuple[int, ...] | None = None  # the machine's, see ``cpu_times``; None: /proc/stat unreadable


class CpuMeter:
    """Snapshots of the process groups' CPU counters and memory, plus the generator's own process.

    Every process matching a group's pattern counts (several gunicorn or postgres processes add up), in
    the first group that matches; the generator and its ancestors (a shell, ``timeout``) never count in
    a server group, the generator's own process (event loop and HTTP threads) is the group ``generator``.
    """

    def __init__(self, groups: Mapping[str, str]) -> None:
        self.groups = {name: re.compile(pattern) for name, pattern in groups.items()}

    def snapshot(self) -> Snapshot:
        members = self._members()
        members[GENERATOR] = [os.getpid()]
        samples = {}
        for pids in members.values():
            for pid in pids:
                sample = process_sample(pid)
                if sample is not None:
                    samples[pid] = sample
        return Snapshot(members, samples, cpu_times(_read("/proc/stat")))

    def _members(self) -> dict[str, list[int]]:
        members: dict[str, list[int]] = {group: [] for group in self.groups}
        ours = _ancestors(os.getpid())
        for pid, line in command_lines().items():
            if pid in ours:
                continue
            group = next((group for group, pattern in self.groups.items() if pattern.search(line)), None)
            if group is not None:
                members[group].append(pid)
        return members


def usage(before: Snapshot, after: Snapshot, seconds: float) -> dict[str, dict[str, float | int]]:
    """Per group between two snapshots: cpu_seconds, cores (cpu_seconds / seconds), rss_mb at ``after``,
    processes.

    A process that started in between counts in full; one that ended is counted by its parent if the
    parent reaped it (postgres backends, prefork workers), so what it had used before is taken off. If its
    parent is known and not in the group (a group of one database's postgres backends, without the
    postmaster), nothing of it is counted: what it used between ``before`` and its end is lost.
    """
    report = {}
    for group, pids in after.members.items():
        cpu = 0.0
        for pid in pids:
            if pid in after.samples:
                earlier = before.samples.get(pid)
                cpu += after.samples[pid].cpu_seconds - (earlier.cpu_seconds if earlier else 0.0)
        # A member that ended was reaped by its parent, whose children's time now holds all of its CPU,
        # including what it had used before.
        for pid in set(before.members.get(group, ())) - set(after.samples):
            gone = before.samples.get(pid)
            if gone is not None and (not gone.parent or gone.parent in pids):
                cpu -= gone.cpu_seconds
        rss = sum(after.samples[pid].rss_bytes for pid in pids if pid in after.samples)
        report[group] = {
            "cpu_seconds": round(cpu, 2),
            "cores": round(cpu / seconds, 3) if seconds > 0 else 0.0,
            "rss_mb": round(rss / 2**20, 1),
            "processes": len(pids),
        }
    return report


def interleaved(
    sides: Sequence[str], rounds: int, meter: CpuMeter, run_round: Callable[[str, int], object]
) -> dict[str, list[tuple[float, float]]]:
    """Per side, per round: the CPU seconds of the side's processes (`meter`'s group of that name) and the
    wall seconds of `run_round(side, round number)`. Rounds go side after side, the order reversed every
    other round, so that a machine's drift (up to 2x in a day on the shared VMs, swings within minutes)
    falls on every side alike."""
    spent: dict[str, list[tuple[float, float]]] = {side: [] for side in sides}
    for number, side in interleaved_order(sides, rounds):
        before, started = meter.snapshot(), time.monotonic()
        run_round(side, number)
        wall = time.monotonic() - started
        spent[side].append((usage(before, meter.snapshot(), wall)[side]["cpu_seconds"], wall))
    return spent


def interleaved_order(sides: Sequence[str], rounds: int) -> Iterator[tuple[int, str]]:
    """(round number, side) in the order ``interleaved`` runs them: side after side, the order reversed
    every other round (A B, B A, A B, ... for two sides)."""
    for number in range(rounds):
        for side in sides if number % 2 == 0 else sides[::-1]:
            yield number, side


def _ancestors(pid: int) -> set[int]:
    """``pid`` and its parents up to init."""
    chain = set()
    while pid > 1 and pid not in chain:
        chain.add(pid)
        try:
            stat = (PROC / str(pid) / "stat").read_text()
        except OSError:
            break
        pid = int(stat[stat.rindex(")") + 2 :].split()[1])
    return chain


# --- over time: the window in slices, and how much the figures drift from the first to the last ---------


def slice_ends(duration: float, every: float) -> list[float]:
    """Seconds from the window's start at which its slices end: equal slices of about ``every`` s.

    Equal rather than ``every`` s plus a remainder, so no short last slice makes the drift noisy.
    """
    count = max(1, round(duration / every))
    return [duration * index / count for index in range(1, count + 1)]


def series_point(
    t: float,
    seconds: float,
    step_latencies: Sequence[float],
    orders: int,
    processes: Mapping[str, Mapping[str, float | int]],
) -> dict[str, Any]:
    """One slice of the window: ``t`` s from the window's start to the slice's end, ``seconds`` long,
    with the step latencies (s) and orders finished inside it and its ``usage`` per process group."""
    steps = latency_summary(step_latencies)
    return {
        "t": round(t, 1),
        "seconds": round(seconds, 2),
        "orders_per_s": round(orders / seconds, 1) if seconds > 0 else 0.0,
        "steps": steps["count"],
        "step_p50_ms": steps["p50"],
        "step_p99_ms": steps["p99"],
        "rss_mb": {group: figures["rss_mb"] for group, figures in processes.items()},
        "cores": {group: figures["cores"] for group, figures in processes.items()},
    }


def trend(values: Sequence[float | None]) -> dict[str, float | None]:
    """One figure over the slices: first, last, max, growth (last - first) and growth_pct (of first).

    None marks a slice without the figure (no step finished in it); growth then needs both ends.
    """
    first, last = values[0], values[-1]
    growth = round(last - first, 2) if first is not None and last is not None else None
    return {
        "first": first,
        "last": last,
        "max": max((value for value in values if value is not None), default=None),
        "growth": growth,
        "growth_pct": round(growth / first * 100, 1) if growth is not None and first else None,
    }


def drift(series: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """First slice against last (and the worst slice): is memory or latency creeping up over the run?"""
    return {
        "slices": len(series),
        "rss_mb": {
            group: trend([point["rss_mb"][group] for point in series]) for group in series[0]["rss_mb"]
        },
        "step_p50_ms": trend([point["step_p50_ms"] for point in series]),
        "step_p99_ms": trend([point["step_p99_ms"] for point in series]),
    }


def cpu_times(proc_stat: str) -> tuple[int, ...] | None:
    """All CPUs' jiffies from the text of /proc/stat (its first line: ``cpu`` user nice system idle iowait
    irq softirq steal ...); None if there is no such line."""
    first = proc_stat.partition("\n")[0].split()
    return tuple(int(value) for value in first[1:]) if first[:1] == ["cpu"] else None


def busy_and_steal(before: tuple[int, ...] | None, after: tuple[int, ...] | None) -> dict[str, float | None]:
    """Percent of all CPUs' time between two ``cpu_times`` that the machine was busy (user, nice, system,
    irq, softirq) and that the hypervisor gave to other VMs (steal); None if either is unknown.

    Whether the machine did other work, or was slowed by its neighbours, while a run measured the server.
    """
    if before is None or after is None:
        return {"busy_pct": None, "steal_pct": None}
    # The first 8 fields; guest time (9th and 10th) is already counted in user and nice.
    user, nice, system, idle, iowait, irq, softirq, steal = (
        later - earlier for earlier, later in zip(before[:8], after[:8], strict=True)
    )
    total = user + nice + system + idle + iowait + irq + softirq + steal
    if total <= 0:
        return {"busy_pct": None, "steal_pct": None}
    busy = user + nice + system + irq + softirq
    return {"busy_pct": round(busy / total * 100, 1), "steal_pct": round(steal / total * 100, 1)}


def cpu_speed_ms() -> float:
    """ms of CPU time a fixed piece of server-like Python work takes, best of CALIBRATION_REPEATS.

    The same code on the same kind of shared VM used half as much CPU again per request on one day as on
    another, without steal time, so a run's CPU figures compare with another day's only alongside this
    (lower is faster). Best of several, because other load only makes it slower; CPU time of this thread,
    so waiting does not count.
    """
    best = math.inf
    for _ in range(CALIBRATION_REPEATS):
        began = time.thread_time()
        _calibration_work(CALIBRATION_ITERATIONS)
        best = min(best, time.thread_time() - began)
    return round(best * 1000, 1)


def round_trip_us(
    postgres: str | None, redis_url: str | None, count: int = ROUND_TRIPS
) -> dict[str, float | None]:
    """µs of wall time per round trip, best of ROUND_TRIP_REPEATS loops of ``count``: ``SELECT 1`` on a new
    psycopg connection (autocommit) to ``postgres`` (a conninfo string) and Redis ``PING`` to ``redis_url``;
    None for a service not given. What the pure-Python calibration misses: the client's and the server's
    system calls, the loopback, the services' own speed."""
    figures: dict[str, float | None] = {"select1_us": None, "redis_ping_us": None}
    if postgres is not None:
        import psycopg  # only when probing: bench.fleet runs against servers without one

        with psycopg.connect(postgres, autocommit=True) as connection, connection.cursor() as cursor:

            def select() -> None:
                cursor.execute("SELECT 1")
                cursor.fetchone()

            figures["select1_us"] = _best_loop_us(select, count)
    if redis_url is not None:
        import redis

        client = redis.Redis.from_url(redis_url)
        try:
            figures["redis_ping_us"] = _best_loop_us(client.ping, count)
        finally:
            client.close()
    return figures


def _best_loop_us(call: Callable[[], object], count: int) -> float:
    call()  # connected, first statement parsed
    best = math.inf
    for _ in range(ROUND_TRIP_REPEATS):
        began = time.perf_counter()
        for _ in range(count):
            call()
        best = min(best, time.perf_counter() - began)
    return round(best / count * 1e6, 1)


def broker_publishes(redis_url: str | None) -> int | None:
    """How many messages kombu's Redis transport has pushed onto its queues on ``redis_url``'s server
    since it started (``LPUSH`` calls: only kombu pushes onto lists there), or None without a URL or when
    it cannot be asked. Over a window and per order: the Celery tasks an order cost, each a hop to pay."""
    if redis_url is None:
        return None
    import redis

    client = redis.Redis.from_url(redis_url)
    try:
        stats = client.info("commandstats")
    except redis.RedisError:
        return None
    finally:
        client.close()
    return int(stats.get("cmdstat_lpush", {}).get("calls", 0))


def cpu_per_order(
    processes: Mapping[str, Mapping[str, float | int]], orders: int, cal_ms: float | None
) -> dict[str, Any]:
    """Server CPU per order over a window: the CPU seconds of every group but the generator (``usage``'s
    figures) / the orders finished in the window, in ms; ``at_reference_ms`` scaled to the reference hour
    (``* REFERENCE_CAL_MS / cal_ms``); None without orders (an idle run)."""
    server = {
        group: float(figures["cpu_seconds"]) for group, figures in processes.items() if group != GENERATOR
    }
    total = sum(server.values())
    per_order = total * 1000 / orders if orders else None
    return {
        "orders": orders,
        "server_cpu_seconds": round(total, 2),
        "server_ms": round(per_order, 3) if per_order is not None else None,
        "at_reference_ms": round(per_order * REFERENCE_CAL_MS / cal_ms, 3)
        if per_order is not None and cal_ms
        else None,
        "by_group_ms": {
            group: round(seconds * 1000 / orders, 3) if orders else None for group, seconds in server.items()
        },
    }


def _calibration_work(iterations: int) -> None:
    """What a request handler does, ``iterations`` times: build a small document, serialize and parse it,
    add up its numbers and format a line."""
    for iteration in range(iterations):
        document = {
            f"field_{index}": index * iteration % 1000 if index % 2 else f"value {index}"
            for index in range(50)
        }
        parsed = json.loads(json.dumps(document))
        numbers = sum(value for value in parsed.values() if isinstance(value, int))
        parsed["summary"] = f"request {iteration:06d}: mean {numbers / 25:.2f}, {parsed['field_0']}"


def machine() -> dict[str, str | int | float]:
    """What the numbers were measured on."""
    info: dict[str, str | int | float] = {
        "cpus": os.cpu_count() or 0,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "load_average_1m": round(os.getloadavg()[0], 2),
    }
    for line in _read("/proc/cpuinfo").splitlines():
        if line.startswith("model name"):
            info["cpu_model"] = line.split(":", 1)[1].strip()
            break
    for line in _read("/proc/meminfo").splitlines():
        if line.startswith("MemTotal:"):
            info["memory_gb"] = round(int(line.split()[1]) / 2**20, 1)
            break
    return info


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError:
        return ""
