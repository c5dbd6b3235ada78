"""--unbound (issue 41): the pool of missions posted without a robot, where each goes, when it reached
which robot, and the figures of a run: bind latency, first orders, total distance against the optimum."""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, Any

from bench import measure

if TYPE_CHECKING:
    from bench.fleet import Load


class Pool:
    """--unbound: the missions posted without a robot, where they go and when they reached which robot."""

    def __init__(self, seed: int = 41) -> None:
        self.places = random.Random(seed)  # robots' places, then missions' destinations
        self.posted = 0
        self.outstanding = 0  # posted, not finished
        self.destinations: dict[str, tuple[float, float]] = {}
        self.started: set[str] = set()  # the start phase's (or burst's) missions: the measured ones
        self.sent_at: dict[str, tuple[float, float]] = {}  # POST sent: monotonic, wall clock
        self.first_orders: dict[str, tuple[float, Load]] = {}  # first order received (monotonic), by whom
        self.bound_at: dict[str, float] = {}  # the server's binding time (wall clock)

    def figures(self) -> dict[str, Any]:
        """Bind latency (POST sent -> the server's bound_at), POST -> first order, the last POST -> the last
        binding, the first orders' rate, and the start phase's total distance against the optimum."""
        started = sorted(self.started & self.sent_at.keys())
        bound = [name for name in started if name in self.bound_at]
        reached = [name for name in started if name in self.first_orders]
        last_post = max((self.sent_at[name][1] for name in started), default=0.0)
        last_binding = max((self.bound_at[name] for name in bound), default=None)
        first_times = sorted(self.first_orders[name][0] for name in reached)
        span = first_times[-1] - first_times[0] if len(first_times) > 1 else 0.0
        return {
            "missions": len(started),
            "bound": len(bound),
            "reached_a_robot": len(reached),
            "bind_latency_ms": measure.latency_summary(
                [self.bound_at[name] - self.sent_at[name][1] for name in bound]
            ),
            "first_order_latency_ms": measure.latency_summary(
                [self.first_orders[name][0] - self.sent_at[name][0] for name in reached]
            ),
            "last_post_to_last_binding_ms": None
            if last_binding is None
            else round(1000 * (last_binding - last_post), 1),
            "first_orders_per_second": round((len(first_times) - 1) / span, 1) if span > 0 else None,
            **self._distances(reached),
        }

    def _distances(self, reached: list[str]) -> dict[str, Any]:
        """Robot (its place: idle robots stay home) -> first waypoint, summed, against the optimum
        (linear_sum_assignment on the same robots and missions)."""
        import numpy as np
        from scipy.optimize import linear_sum_assignment

        if not reached:
            return {"total_distance_m": None, "optimal_distance_m": None, "over_optimum_percent": None}
        robots = {id(load): (load.x, load.y) for load in (self.first_orders[n][1] for n in reached)}
        total = sum(math.dist(robots[id(self.first_orders[n][1])], self.destinations[n]) for n in reached)
        places = np.array(list(robots.values()))
        goals = np.array([self.destinations[n] for n in reached])
        cost = np.hypot(places[:, None, 0] - goals[None, :, 0], places[:, None, 1] - goals[None, :, 1])
        rows, columns = linear_sum_assignment(cost)
        optimum = float(cost[rows, columns].sum())
        return {
            "total_distance_m": round(total, 1),
            "optimal_distance_m": round(optimum, 1),
            "over_optimum_percent": round(100 * (total - optimum) / optimum, 2) if optimum else 0.0,
        }
