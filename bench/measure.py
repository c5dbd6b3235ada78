"""What a run measures besides messages: latency summaries, CPU and memory of processes, the machine."""

from __future__ import annotations

import math
import os
import platform
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
PAGE_SIZE = os.sysconf("SC_PAGE_SIZE")
PROC = Path("/proc")

# Server process groups by command-line pattern (a regex searched in the command line).
DEFAULT_PROCESS_GROUPS = {
    "api": r"gunicorn|manage\.py runserver|uvicorn",
    "bridge": r"mqtt_bridge",
    "workers": r"celery.*\bworker\b",
    "beat": r"celery.*\bbeat\b",
    "redis": r"redis-server",
    "postgres": r"^postgres|/postgres\b",
    "broker": r"mosquitto",
}
GENERATOR = "generator"


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


def process_sample(pid: int) -> ProcessSample | None:
    """From /proc/<pid>/stat; None if the process is gone."""
    try:
        text = (PROC / str(pid) / "stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2 :].split()  # after "pid (comm) "; comm may contain spaces
    utime, stime, cutime, cstime = (int(value) for value in fields[11:15])
    return ProcessSample((utime + stime + cutime + cstime) / CLOCK_TICKS, int(fields[21]) * PAGE_SIZE)


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


class CpuMeter:
    """CPU seconds and memory per process group between ``start`` and ``stop``.

    Every process matching a group's pattern counts (several gunicorn or postgres processes add up), in
    the first group that matches; the generator and its ancestors (a shell, ``timeout``) never count. A
    process that starts during the window counts in full, one that ends is counted by its parent if
    the parent reaped it (postgres backends, prefork workers).
    """

    def __init__(self, groups: Mapping[str, str]) -> None:
        self.groups = {name: re.compile(pattern) for name, pattern in groups.items()}
        self._start: dict[int, ProcessSample] = {}
        self._start_members: dict[str, list[int]] = {}

    def start(self) -> None:
        self._start_members = self._members()
        self._start = self._sample(self._start_members)

    def stop(self, seconds: float) -> dict[str, dict[str, float | int]]:
        """Per group: cpu_seconds, cores (cpu_seconds / seconds), rss_mb at the end, processes."""
        members = self._members()
        end = self._sample(members)
        report = {}
        for group, pids in members.items():
            cpu = 0.0
            for pid in pids:
                before = self._start.get(pid)
                cpu += end[pid].cpu_seconds - (before.cpu_seconds if before else 0.0) if pid in end else 0.0
            # A member that ended was reaped by its parent, whose children's time now holds all of its
            # CPU, including what it had used before the window.
            for pid in set(self._start_members.get(group, ())) - set(end):
                cpu -= self._start[pid].cpu_seconds if pid in self._start else 0.0
            rss = sum(end[pid].rss_bytes for pid in pids if pid in end)
            report[group] = _usage(cpu, seconds, rss, len(pids))
        return report

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

    @staticmethod
    def _sample(members: Mapping[str, list[int]]) -> dict[int, ProcessSample]:
        samples = {}
        for pids in members.values():
            for pid in pids:
                sample = process_sample(pid)
                if sample is not None:
                    samples[pid] = sample
        return samples


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


class OwnCpu:
    """The generator's own CPU (all its threads) over a window."""

    def __init__(self) -> None:
        self._start = 0.0

    def start(self) -> None:
        self._start = _own().cpu_seconds

    def stop(self, seconds: float) -> dict[str, float | int]:
        own = _own()
        return _usage(own.cpu_seconds - self._start, seconds, own.rss_bytes, 1)


def _own() -> ProcessSample:
    sample = process_sample(os.getpid())
    assert sample is not None
    return sample


def _usage(cpu_seconds: float, seconds: float, rss_bytes: int, processes: int) -> dict[str, float | int]:
    return {
        "cpu_seconds": round(cpu_seconds, 2),
        "cores": round(cpu_seconds / seconds, 3) if seconds > 0 else 0.0,
        "rss_mb": round(rss_bytes / 2**20, 1),
        "processes": processes,
    }


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
