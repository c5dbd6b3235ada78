"""The benchmark's figures over time: CPU and memory between snapshots, slices, drift, their report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from bench import measure, report
from bench.measure import CpuMeter, ProcessSample, Snapshot, interleaved


def test_usage_between_snapshots_counts_new_processes_in_full_and_reaped_ones_by_their_parent() -> None:
    before = Snapshot(
        {"postgres": [10, 11], "generator": [99]},
        {10: ProcessSample(5.0, 2**20), 11: ProcessSample(1.5, 2**20), 99: ProcessSample(2.0, 2**20)},
    )
    # 11 ended (reaped by 10, whose children's time now holds its 1.5 s and 0.5 s more); 12 is new.
    after = Snapshot(
        {"postgres": [10, 12], "generator": [99]},
        {
            10: ProcessSample(7.5, 3 * 2**20),
            12: ProcessSample(0.25, 2**20),
            99: ProcessSample(3.0, 5 * 2**20),
        },
    )

    usage = measure.usage(before, after, seconds=2.0)

    assert usage["postgres"] == {"cpu_seconds": 1.25, "cores": 0.625, "rss_mb": 4.0, "processes": 2}
    assert usage["generator"] == {"cpu_seconds": 1.0, "cores": 0.5, "rss_mb": 5.0, "processes": 1}


def test_snapshot_holds_the_generator_as_its_own_group() -> None:
    snapshot = measure.CpuMeter({"nothing": r"^no process has this command line$"}).snapshot()

    assert snapshot.members["nothing"] == []
    (pid,) = snapshot.members[measure.GENERATOR]
    assert snapshot.samples[pid].rss_bytes > 0
    assert snapshot.cpu_times is not None and len(snapshot.cpu_times) >= 8  # the machine's, user .. steal


# user nice system idle iowait irq softirq steal guest guest_nice, all CPUs, in jiffies
PROC_STAT_BEFORE = (
    "cpu  1000 20 300 50000 40 0 10 100 500 0\ncpu0 500 10 150 25000 20 0 5 50 250 0\nintr 1 2\n"
)


def test_cpu_times_are_the_first_cpu_line_of_proc_stat() -> None:
    assert measure.cpu_times(PROC_STAT_BEFORE) == (1000, 20, 300, 50000, 40, 0, 10, 100, 500, 0)
    assert measure.cpu_times("") is None  # /proc/stat unreadable


def test_busy_and_steal_are_shares_of_all_cpu_time_between_two_readings() -> None:
    before = measure.cpu_times(PROC_STAT_BEFORE)
    # +1000 jiffies: 300 user, 50 nice, 100 system, 520 idle, 10 iowait, 5 irq, 5 softirq, 10 steal;
    # guest time (+200) is part of user already and must not count twice.
    after = (1300, 70, 400, 50520, 50, 5, 15, 110, 700, 0)

    assert measure.busy_and_steal(before, after) == {"busy_pct": 46.0, "steal_pct": 1.0}


def test_busy_and_steal_are_unknown_without_proc_stat_or_time_between() -> None:
    before = measure.cpu_times(PROC_STAT_BEFORE)
    unknown = {"busy_pct": None, "steal_pct": None}

    assert measure.busy_and_steal(None, before) == unknown
    assert measure.busy_and_steal(before, None) == unknown
    assert measure.busy_and_steal(before, before) == unknown


@pytest.mark.parametrize(
    ("duration", "every", "ends"),
    [
        (300, 30, [30.0 * i for i in range(1, 11)]),
        (10, 3, [10 / 3, 20 / 3, 10.0]),  # equal slices, no 1-s remainder
        (10, 30, [10.0]),  # a window shorter than a slice is one slice
        (100, 40, [50.0, 100.0]),
    ],
)
def test_slices_are_equal_and_end_with_the_window(duration: float, every: float, ends: list[float]) -> None:
    assert measure.slice_ends(duration, every) == pytest.approx(ends)


def test_series_point_has_the_slice_figures() -> None:
    latencies = [i / 1000 for i in range(1, 101)]  # 1 .. 100 ms
    processes = {
        "api": {"cpu_seconds": 3.0, "cores": 0.1, "rss_mb": 250.5, "processes": 3},
        "generator": {"cpu_seconds": 6.0, "cores": 0.2, "rss_mb": 80.0, "processes": 1},
    }

    point = measure.series_point(60.04, 30.02, latencies, orders=1501, processes=processes)

    assert point == {
        "t": 60.0,
        "seconds": 30.02,
        "orders_per_s": 50.0,
        "steps": 100,
        "step_p50_ms": 50.0,
        "step_p99_ms": 99.0,
        "rss_mb": {"api": 250.5, "generator": 80.0},
        "cores": {"api": 0.1, "generator": 0.2},
    }


def test_series_point_of_a_slice_without_steps() -> None:
    point = measure.series_point(30.0, 30.0, [], orders=0, processes={})

    assert point["steps"] == 0
    assert point["step_p50_ms"] is point["step_p99_ms"] is None
    assert point["orders_per_s"] == 0.0


def test_trend_is_first_against_last_with_the_worst_in_between() -> None:
    assert measure.trend([200.0, 260.0, 210.0]) == {
        "first": 200.0,
        "last": 210.0,
        "max": 260.0,
        "growth": 10.0,
        "growth_pct": 5.0,
    }
    assert measure.trend([100.0, 98.3])["growth"] == -1.7  # rounded, no float noise
    assert measure.trend([5.0]) == {"first": 5.0, "last": 5.0, "max": 5.0, "growth": 0.0, "growth_pct": 0.0}


def test_trend_without_a_figure_at_one_end_has_no_growth() -> None:
    assert measure.trend([None, 12.0, None]) == {
        "first": None,
        "last": None,
        "max": 12.0,
        "growth": None,
        "growth_pct": None,
    }
    assert measure.trend([None, None])["max"] is None
    # A group without processes at first (0 MB): growth in MB, no percentage of nothing.
    assert measure.trend([0.0, 30.0]) == {
        "first": 0.0,
        "last": 30.0,
        "max": 30.0,
        "growth": 30.0,
        "growth_pct": None,
    }


def series() -> list[dict[str, Any]]:
    """Three 10-s slices: the workers' memory grows, the api's stays flat, p99 doubles."""
    return [
        measure.series_point(
            10.0 * (i + 1),
            10.0,
            [0.010] * 98 + [0.040 * (i + 1)] * 2,
            orders=100,
            processes={
                "api": {"cpu_seconds": 1.0, "cores": 0.1, "rss_mb": 250.0, "processes": 3},
                "workers": {"cpu_seconds": 2.0, "cores": 0.2, "rss_mb": 200.0 + 20 * i, "processes": 1},
            },
        )
        for i in range(3)
    ]


def test_drift_per_group_and_for_step_latency() -> None:
    drift = measure.drift(series())

    assert drift["slices"] == 3
    assert drift["rss_mb"]["api"] == {
        "first": 250.0,
        "last": 250.0,
        "max": 250.0,
        "growth": 0.0,
        "growth_pct": 0.0,
    }
    assert drift["rss_mb"]["workers"] == {
        "first": 200.0,
        "last": 240.0,
        "max": 240.0,
        "growth": 40.0,
        "growth_pct": 20.0,
    }
    assert drift["step_p50_ms"] == {
        "first": 10.0,
        "last": 10.0,
        "max": 10.0,
        "growth": 0.0,
        "growth_pct": 0.0,
    }
    assert (drift["step_p99_ms"]["first"], drift["step_p99_ms"]["last"]) == (40.0, 120.0)
    assert drift["step_p99_ms"]["growth_pct"] == 200.0


def test_series_plot_is_written_for_runs_and_idle_fleets(tmp_path: Path) -> None:
    for mode in ("run", "idle"):
        result = {"mode": mode, "label": "", "run_id": "abc", "options": {"robots": 3}, "series": series()}
        path = tmp_path / f"{report.run_stem(result)}-series.png"

        report.series_plot(result, path)

        assert path.name == f"{mode}-n3-abc-series.png"
        assert path.read_bytes().startswith(b"\x89PNG")


def test_interleaved_rounds_reverse_the_order_every_other_round_and_time_each_side() -> None:
    calls: list[tuple[str, int]] = []
    meter = CpuMeter({"a": r"\Ano process has this command line\Z", "b": r"\Anor this one\Z"})

    spent = interleaved(["a", "b"], 3, meter, lambda side, number: calls.append((side, number)))

    assert calls == [("a", 0), ("b", 0), ("b", 1), ("a", 1), ("a", 2), ("b", 2)]
    assert [len(spent[side]) for side in ("a", "b")] == [3, 3]
    assert all(cpu == 0 and wall >= 0 for rounds in spent.values() for cpu, wall in rounds)
