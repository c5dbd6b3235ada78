"""The assignment of unbound missions (``dispatch.assignment.assign``) in a burst: idle robots and missions
spread uniformly over one map (seeded), all free, one priority; every robot capable of every mission, or
with a size's "/lift" every second mission asks for the label "lift" that every second robot carries.
Reports the wall and CPU time of ``assign`` and its total distance against first-come greedy (each mission,
oldest first, takes its nearest free capable robot) and against the optimum (``linear_sum_assignment``
alone on the raw distances, the pairs no robot can do excluded):

    .venv/bin/python -m bench.assignment [--sizes 100x100 1000x1000 1000x1000/lift] [--repeats 5]

Results: bench/HISTORY.md, "Assignment".
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from scipy.optimize import linear_sum_assignment

from bench.measure import cpu_speed_ms
from dispatch.assignment import CandidateRobot, Pose, RobotSelector, UnboundMission, assign

MAP = "warehouse"
MAP_SIDE_M = 200.0  # a square map of this side, in metres
LIFT = "lift"
SEED = 41
EPOCH = datetime(2026, 11, 28, tzinfo=UTC)


@dataclass(frozen=True)
class Burst:
    missions: list[UnboundMission]  # oldest first
    robots: list[CandidateRobot]

    def distances(self) -> np.ndarray:
        """(missions x robots); infinite where the robot lacks a label the mission asks for."""
        starts = np.array([(m.start.x, m.start.y) for m in self.missions if m.start])
        poses = np.array([(r.pose.x, r.pose.y) for r in self.robots if r.pose])
        matrix = np.hypot(starts[:, None, 0] - poses[None, :, 0], starts[:, None, 1] - poses[None, :, 1])
        capable = [[m.selector.labels <= r.labels for r in self.robots] for m in self.missions]
        return np.where(capable, matrix, np.inf)


def burst(missions: int, robots: int, lift: bool, seed: int = SEED) -> Burst:
    """Missions posted a millisecond apart and idle robots, all at uniform random places on one map."""
    rng = np.random.default_rng(seed)
    starts = rng.uniform(0.0, MAP_SIDE_M, size=(missions, 2))
    poses = rng.uniform(0.0, MAP_SIDE_M, size=(robots, 2))
    idle_for = rng.uniform(0.0, 600.0, size=robots)
    return Burst(
        missions=[
            UnboundMission(
                name=f"m{index}",
                priority=0,
                created=EPOCH + timedelta(milliseconds=index),
                selector=RobotSelector(labels=frozenset({LIFT} if lift and index % 2 else ())),
                start=Pose(float(x), float(y), MAP),
                maps=frozenset({MAP}),
            )
            for index, (x, y) in enumerate(starts)
        ],
        robots=[
            CandidateRobot(
                name=f"r{index}",
                labels=frozenset({LIFT} if lift and index % 2 else ()),
                robot_type=None,
                action_types=frozenset(),
                pose=Pose(float(x), float(y), MAP),
                online=True,
                idle=True,
                battery_ok=True,
                enabled_maps=frozenset({MAP}),
                idle_since=EPOCH - timedelta(seconds=float(idle)),
            )
            for index, ((x, y), idle) in enumerate(zip(poses, idle_for, strict=True))
        ],
    )


def greedy(matrix: np.ndarray) -> tuple[int, float]:
    """First come: each mission, oldest first, takes its nearest free capable robot. How many are bound,
    and their total distance."""
    free = np.ones(matrix.shape[1], dtype=bool)
    total = 0.0
    for row in matrix:
        nearest = int(np.argmin(np.where(free, row, np.inf)))
        if free[nearest] and np.isfinite(row[nearest]):
            total += float(row[nearest])
            free[nearest] = False
    return int((~free).sum()), total


def optimal_distance(matrix: np.ndarray) -> float:
    rows, columns = linear_sum_assignment(matrix)
    return float(matrix[rows, columns].sum())


@dataclass(frozen=True)
class Row:
    missions: int
    robots: int
    lift: bool
    wall_ms: list[float]
    cpu_ms: list[float]
    bound: int
    assigned: float
    greedy_bound: int
    greedy: float
    optimum: float


def measure(missions: int, robots: int, lift: bool, repeats: int) -> Row:
    case = burst(missions, robots, lift)
    wall, cpu = [], []
    for _ in range(repeats):
        began_wall, began_cpu = time.perf_counter(), time.process_time()
        result = assign(case.missions, case.robots)
        wall.append((time.perf_counter() - began_wall) * 1000)
        cpu.append((time.process_time() - began_cpu) * 1000)
    matrix = case.distances()
    row_of = {m.name: i for i, m in enumerate(case.missions)}
    column_of = {r.name: j for j, r in enumerate(case.robots)}
    assigned = sum(float(matrix[row_of[m], column_of[r]]) for m, r in result.bindings.items())
    greedy_bound, greedy_total = greedy(matrix)
    return Row(
        missions=missions,
        robots=robots,
        lift=lift,
        wall_ms=wall,
        cpu_ms=cpu,
        bound=len(result.bindings),
        assigned=assigned,
        greedy_bound=greedy_bound,
        greedy=greedy_total,
        optimum=optimal_distance(matrix),
    )


def table(rows: list[Row]) -> str:
    lines = [
        "| missions x robots | labels | bound: `assign`, greedy | `assign` wall ms (median, max) "
        "| CPU ms (median) | CPU µs per mission | total distance m: `assign` | greedy | optimum "
        "| `assign` over optimum | greedy over optimum |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        cpu = statistics.median(row.cpu_ms)
        over, greedy_over = (row.assigned / row.optimum - 1) * 100, (row.greedy / row.optimum - 1) * 100
        lines.append(
            f"| {row.missions} x {row.robots} | {'half ask lift' if row.lift else 'none'} "
            f"| {row.bound}, {row.greedy_bound} "
            f"| {statistics.median(row.wall_ms):.0f}, {max(row.wall_ms):.0f} | {cpu:.0f} "
            f"| {cpu / row.missions * 1000:.0f} | {row.assigned:,.0f} | {row.greedy:,.0f} "
            f"| {row.optimum:,.0f} | {over:+.3f} % | {greedy_over:+.1f} % |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--sizes",
        nargs="+",
        default=["100x100", "1000x1000", "1000x1000/lift"],
        help="MISSIONSxROBOTS[/lift]",
    )
    parser.add_argument("--repeats", type=int, default=5)
    arguments = parser.parse_args()
    print(f"calibration work: {cpu_speed_ms()} ms (lower is faster)")
    rows = []
    for size in arguments.sizes:
        counts, _, lift = size.partition("/")
        missions, robots = (int(count) for count in counts.split("x"))
        rows.append(measure(missions, robots, lift == LIFT, arguments.repeats))
    print(table(rows))


if __name__ == "__main__":
    main()
