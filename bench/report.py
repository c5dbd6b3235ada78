"""Markdown tables and plots from ``bench.fleet`` result files.

``python -m bench.report bench/results/*.json --output bench --name latest`` writes ``latest.md`` (one row
per run) and ``latest.png`` (step latency and throughput against fleet size). ``bench.fleet`` also writes
each run's own Markdown and its time series plot with ``run_markdown`` and ``series_plot``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.measure import GENERATOR, REFERENCE_CAL_MS

SERVER_GROUPS = ("api", "bridge", "workers", "beat", "redis", "postgres", "broker")


def run_stem(result: dict[str, Any]) -> str:
    """A run's file names without extension: ``<mode>-n<N>-<run id>``."""
    return f"{result['mode']}-n{result['options']['robots']}-{result['run_id']}"


def run_markdown(result: dict[str, Any]) -> str:
    """One run: its settings, its figures, CPU per process group and the drift over the window."""
    options = result["options"]
    title = result["label"] or result["mode"]
    lines = [
        f"## {title}: {options['robots']} robots ({result['mode']}, run {result['run_id']})",
        "",
        f"{_settings(options)}; window {result['window_seconds']} s from {result['started_at']}.",
        f"Machine: {machine_line(result['machine'])}.",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    throughput = result["throughput"]
    if result["mode"] == "run":
        step, start, missions = result["step_latency_ms"], result["start_latency_ms"], result["missions"]
        lines += [
            f"| orders/s | {throughput['orders_per_second']} |",
            f"| step latency p50 / p95 / p99 / max (ms) | {_latency(step, 'p50', 'p95', 'p99', 'max')} "
            f"({step['count']} steps) |",
            f"| start latency p50 / p99 / max (ms) | {_latency(start, 'p50', 'p99', 'max')} "
            f"({start['count']} starts) |",
            f"| missions completed / failed / abandoned | {missions['completed']} / "
            f"{_value(missions['failed'])} / {missions['abandoned']} |",
        ]
        if missions["failure_reasons"]:
            reasons = "; ".join(f"{count}x {reason}" for reason, count in missions["failure_reasons"].items())
            lines.append(f"| failure reasons | {reasons.replace('|', '/')} |")
    errors = {key: count for key, count in result["errors"].items() if key != "samples" and count}
    lag, machine = result["generator_tick_lag_ms"], result["machine"]
    if result["mode"] == "run":
        per_order = result.get("cpu_per_order") or {}
        lines += [
            f"| server CPU per order (ms; all server groups / orders in the window) | "
            f"{_value(per_order.get('server_ms'))} |",
            f"| server CPU per order at the reference hour (ms x {REFERENCE_CAL_MS:g} / cal) | "
            f"{_value(per_order.get('at_reference_ms'))} |",
        ]
    lines += [
        f"| errors | {', '.join(f'{key} {count}' for key, count in errors.items()) or 'none'} |",
        f"| server settled after the fleet came online (s) | {_value(result.get('settle_seconds'))} |",
        f"| CPU speed at the start (ms of calibration work; lower is faster) | "
        f"{_value(machine.get('cpu_speed_ms'))} |",
        f"| round trips at the start: SELECT 1 / Redis PING (µs) | {_value(machine.get('select1_us'))} / "
        f"{_value(machine.get('redis_ping_us'))} |",
        f"| machine busy / steal over the window (% of all CPUs) | {_value(machine.get('busy_pct'))} / "
        f"{_value(machine.get('steal_pct'))} |",
        f"| states/s published | {throughput['states_per_second']} |",
        f"| generator state-tick lag p99 / max (ms) | {_value(lag['p99'])} / {_value(lag['max'])} |",
        "",
        "| process group | CPU s | cores | RSS MB | processes |",
        "|---|---|---|---|---|",
    ]
    for group, usage in result["cpu"].items():
        figures = (usage["cpu_seconds"], usage["cores"], usage["rss_mb"], usage["processes"])
        lines.append(f"| {group} | " + " | ".join(str(figure) for figure in figures) + " |")
    lines.append(
        f"| server total | {_server_cpu(result, 'cpu_seconds')} | {_server_cpu(result, 'cores')} | | |"
    )
    return "\n".join([*lines, "", *_drift_markdown(result)]) + "\n"


def run_line(result: dict[str, Any]) -> str:
    """One run on one line for the console: throughput, latency, server CPU per order (as measured and at
    the reference hour), the calibration and the round trips at the run's start."""
    machine, per_order = result["machine"], result.get("cpu_per_order") or {}
    cal = machine.get("cpu_speed_ms")
    if result["mode"] == "run":
        step = result["step_latency_ms"]
        figures = (
            f"{result['throughput']['orders_per_second']} orders/s, step p50 / p99 {_value(step['p50'])} / "
            f"{_value(step['p99'])} ms, server CPU per order {_value(per_order.get('server_ms'))} ms "
            f"({_value(per_order.get('at_reference_ms'))} ms scaled to cal {REFERENCE_CAL_MS:g}: "
            f"x {REFERENCE_CAL_MS:g} / {_value(cal)}), Celery tasks per order "
            f"{_value(result.get('tasks_per_order'))}"
        )
    else:
        figures = f"server {_server_cpu(result, 'cores')} cores"
    return (
        f"{figures}; cal {_value(cal)} ms (lower is faster), round trips SELECT 1 "
        f"{_value(machine.get('select1_us'))} µs, Redis PING {_value(machine.get('redis_ping_us'))} µs"
    )


def _drift_markdown(result: dict[str, Any]) -> list[str]:
    """First slice against last, so "flat" can be checked at a glance; the slices are in the JSON."""
    drift = result["drift"]
    length = round(result["window_seconds"] / drift["slices"], 1)
    lines = [
        f"Over the window: {drift['slices']} slices of about {length} s "
        f"(`--sample-every {result['options']['sample_every']:g}`), "
        f"plotted in `{run_stem(result)}-series.png`.",
        "",
        "| drift | first slice | last slice | max slice | growth | growth % |",
        "|---|---|---|---|---|---|",
    ]
    rows = {f"RSS MB {group}": trend for group, trend in drift["rss_mb"].items()}
    if result["mode"] == "run":
        rows |= {"step p50 ms": drift["step_p50_ms"], "step p99 ms": drift["step_p99_ms"]}
    for name, trend in rows.items():
        cells = [name, *(_value(trend[key]) for key in ("first", "last", "max"))]
        cells += [_signed(trend["growth"]), _signed(trend["growth_pct"])]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def summary_markdown(results: Sequence[dict[str, Any]]) -> str:
    """One row per run, ordered by mode, label, delay and fleet size."""
    header = (
        "| label | mode | N | K | Q | delay s | state Hz | orders/s "
        "| step p50 | step p95 | step p99 | step max | start p50 | start p99 "
        "| missions done / failed | server cores | " + " | ".join(SERVER_GROUPS) + " | generator "
        "| server CPU ms/order | at cal 134 | CPU speed ms | SELECT 1 µs | PING µs |"
    )
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for result in sorted(results, key=_order):
        options, step, start = result["options"], result["step_latency_ms"], result["start_latency_ms"]
        running = result["mode"] == "run"
        cpu = result["cpu"]
        cells = [
            result["label"] or "-",
            result["mode"],
            options["robots"],
            options["nodes"] if running else "-",
            options["queue"] if running else "-",
            options["delay"] if running else "-",
            options["state_hz"],
            result["throughput"]["orders_per_second"] if running else "-",
            *(_value(step[key]) if running else "-" for key in ("p50", "p95", "p99", "max")),
            *(_value(start[key]) if running else "-" for key in ("p50", "p99")),
            f"{result['missions']['completed']} / {_value(result['missions']['failed'])}" if running else "-",
            _server_cpu(result, "cores"),
            *(cpu[group]["cores"] if group in cpu else "-" for group in SERVER_GROUPS),
            cpu[GENERATOR]["cores"],
            *(
                _value((result.get("cpu_per_order") or {}).get(key))
                for key in ("server_ms", "at_reference_ms")
            ),
            # runs from before these were measured: -
            *(_value(result["machine"].get(key)) for key in ("cpu_speed_ms", "select1_us", "redis_ping_us")),
        ]
        lines.append("| " + " | ".join(str(cell) for cell in cells) + " |")
    notes = (
        "Latencies in ms; CPU in cores (CPU seconds per second of the measurement window); server CPU per "
        "order: the server groups' CPU seconds in the window / orders finished in it, in ms, and scaled to "
        f"the reference hour (x {REFERENCE_CAL_MS:g} / CPU speed: what it would have been on the machine "
        "as fast as then; a slower machine scales down); CPU speed (cal): ms of fixed calibration work at "
        "the run's start (lower is faster); SELECT 1 and PING: µs per round trip to the stack's PostgreSQL "
        "and Redis at the run's start."
    )
    machines = sorted({machine_line(result["machine"]) for result in results})
    return "\n".join([*lines, "", notes, *(f"Machine: {line}." for line in machines)]) + "\n"


def plot(results: Sequence[dict[str, Any]], path: Path) -> None:
    """Step latency (p50, p99) and throughput against fleet size, one line per label and delay."""
    plt = _pyplot()
    runs = [result for result in results if result["mode"] == "run"]
    idle = [result for result in results if result["mode"] == "idle"]
    panels = 3 if idle else 2
    figure, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.2), layout="constrained")
    latency, throughput = axes[0], axes[1]
    for (label, delay), series in _series(runs).items():
        name = f"{label} delay {delay:g} s" if label else f"delay {delay:g} s"
        sizes = [result["options"]["robots"] for result in series]
        (line,) = latency.plot(
            sizes, [r["step_latency_ms"]["p50"] for r in series], marker="o", label=f"{name} p50"
        )
        latency.plot(
            sizes,
            [r["step_latency_ms"]["p99"] for r in series],
            marker="^",
            linestyle="--",
            color=line.get_color(),
            label=f"{name} p99",
        )
        throughput.plot(sizes, [r["throughput"]["orders_per_second"] for r in series], marker="o", label=name)
    latency.set(title="Step latency", xlabel="robots", ylabel="ms", yscale="log")
    throughput.set(title="Throughput", xlabel="robots", ylabel="orders / s", ylim=(0, None))
    if idle:
        by_label: dict[str, list[dict[str, Any]]] = {}
        for result in sorted(idle, key=lambda r: r["options"]["robots"]):
            by_label.setdefault(result["label"], []).append(result)
        for label, series in by_label.items():
            axes[2].plot(
                [r["options"]["robots"] for r in series],
                [_server_cpu(r, "cores") for r in series],
                marker="o",
                label=label or "idle",
            )
        axes[2].set(title="Idle fleet: server CPU", xlabel="robots", ylabel="cores", ylim=(0, None))
    sizes = sorted({result["options"]["robots"] for result in results})
    for axis in axes:
        axis.set_xscale("log")
        axis.set_xticks(sizes, [str(size) for size in sizes])
        axis.minorticks_off()
        axis.grid(True, alpha=0.3)
        if axis.get_legend_handles_labels()[0]:
            axis.legend(fontsize="small")
    figure.savefig(path, dpi=110)
    plt.close(figure)


def series_plot(result: dict[str, Any], path: Path) -> None:
    """One run over time: RSS growth per process group, and (missions only) step latency p50/p99 per slice."""
    plt = _pyplot()
    series = result["series"]
    times = [point["t"] for point in series]
    panels = 2 if result["mode"] == "run" else 1
    figure, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.2), layout="constrained", squeeze=False)
    memory = axes[0][0]
    # Growth rather than RSS: groups differ by 100x (postgres counts its shared buffers once per backend),
    # so on one absolute scale a leak of a small group would be a flat line.
    for group, first in series[0]["rss_mb"].items():
        values = [point["rss_mb"][group] for point in series]
        if any(values):  # a group with no process (e.g. no beat) would only crowd the legend
            memory.plot(
                times,
                [value - first for value in values],
                marker=".",
                linestyle="--" if group == GENERATOR else "-",
                label=f"{group} ({first:g} MB)",
            )
    memory.set(title="Memory: RSS growth since the first slice", ylabel="MB")
    if panels == 2:
        latency = axes[0][1]
        for key, name, marker in (("step_p50_ms", "p50", "o"), ("step_p99_ms", "p99", "^")):
            latency.plot(times, [_nan(point[key]) for point in series], marker=marker, label=name)
        latency.set(title="Step latency per slice", ylabel="ms", ylim=(0, None))
    figure.suptitle(
        f"{result['label'] or result['mode']}: {result['options']['robots']} robots, run {result['run_id']}"
    )
    for axis in axes[0]:
        axis.set(xlabel="s into the window", xlim=(0, None))
        axis.grid(True, alpha=0.3)
        if axis.get_legend_handles_labels()[0]:
            axis.legend(fontsize="small")
    figure.savefig(path, dpi=110)
    plt.close(figure)


def write_summary(results: Sequence[dict[str, Any]], output: Path, name: str) -> tuple[Path, Path]:
    output.mkdir(parents=True, exist_ok=True)
    table, image = output / f"{name}.md", output / f"{name}.png"
    table.write_text(summary_markdown(results))
    plot(results, image)
    return table, image


# --- A/B: two source trees' runs in interleaved pairs (bench.suite --ab) ----------------------------------

AB_FIGURES = {  # name in the comparison -> how to read it from a run's result
    "cpu_ms_per_order": lambda r: (r.get("cpu_per_order") or {}).get("server_ms"),
    "cpu_ms_at_cal_134": lambda r: (r.get("cpu_per_order") or {}).get("at_reference_ms"),
    "orders_per_s": lambda r: r["throughput"]["orders_per_second"],
    "step_p50_ms": lambda r: r["step_latency_ms"]["p50"],
    "step_p99_ms": lambda r: r["step_latency_ms"]["p99"],
    "start_p99_ms": lambda r: r["start_latency_ms"]["p99"],
    "tasks_per_order": lambda r: r.get("tasks_per_order"),
    "cal_ms": lambda r: r["machine"].get("cpu_speed_ms"),
    "select1_us": lambda r: r["machine"].get("select1_us"),
    "redis_ping_us": lambda r: r["machine"].get("redis_ping_us"),
}


def ab_comparison(
    pairs: Sequence[dict[str, dict[str, dict[str, Any]]]],
    order: Sequence[tuple[int, str]],
    trees: dict[str, str],
) -> dict[str, Any]:
    """Per run of the suite: each pair's figures of side ``a`` (the reference) and ``b`` (this tree), the
    ratio b / a of their server CPU per order (below 1: this tree takes less), the median ratio over the
    pairs, and the medians of every figure per side. ``pairs[i][side][run name]`` is a result of bench.fleet;
    ``order`` is the order the runs went in, ``trees`` names each side's source."""
    names = list(pairs[0]["a"])
    runs = {}
    for name in names:
        rows = []
        for pair in pairs:
            figures = {
                side: {key: read(pair[side][name]) for key, read in AB_FIGURES.items()} for side in "ab"
            }
            a, b = figures["a"]["cpu_ms_per_order"], figures["b"]["cpu_ms_per_order"]
            rows.append({**figures, "cpu_ratio": round(b / a, 3) if a and b is not None else None})
        ratios = [row["cpu_ratio"] for row in rows if row["cpu_ratio"] is not None]
        runs[name] = {
            "pairs": rows,
            "median_cpu_ratio": round(statistics.median(ratios), 3) if ratios else None,
            "median": {
                side: {
                    key: _median([row[side][key] for row in rows if row[side][key] is not None])
                    for key in AB_FIGURES
                }
                for side in "ab"
            },
        }
    return {
        "trees": trees,
        "pairs": len(pairs),
        "order": [f"{side}{n + 1}" for n, side in order],
        "runs": runs,
    }


def ab_markdown(comparison: dict[str, Any]) -> str:
    trees = comparison["trees"]
    lines = [
        f"## A/B: a = {trees['a']}, b = {trees['b']}",
        "",
        f"{comparison['pairs']} pairs, each run on a freshly started stack of its side's tree, in the order "
        f"{' '.join(comparison['order'])}. Ratio: b / a of server CPU per order (below 1: b takes less).",
    ]
    for name, run in comparison["runs"].items():
        lines += [
            "",
            f"### {name}: median ratio b / a {_value(run['median_cpu_ratio'])}",
            "",
            "| pair | a CPU ms/order | b CPU ms/order | b / a | a / b orders/s | a / b step p50 ms "
            "| a / b step p99 ms | a / b start p99 ms | a / b tasks/order | a / b cal ms |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        rows = [(str(number + 1), row) for number, row in enumerate(run["pairs"])]
        median = run["median"]
        for label, row in [*rows, ("median", {**median, "cpu_ratio": run["median_cpu_ratio"]})]:
            a, b = row["a"], row["b"]
            cells = [
                label,
                _value(a["cpu_ms_per_order"]),
                _value(b["cpu_ms_per_order"]),
                _value(row["cpu_ratio"]),
            ]
            cells += [
                f"{_value(a[key])} / {_value(b[key])}"
                for key in (
                    "orders_per_s",
                    "step_p50_ms",
                    "step_p99_ms",
                    "start_p99_ms",
                    "tasks_per_order",
                    "cal_ms",
                )
            ]
            lines.append("| " + " | ".join(cells) + " |")
        a, b = median["a"], median["b"]
        lines.append(
            f"\nMedians at the reference hour (x {REFERENCE_CAL_MS:g} / cal): a "
            f"{_value(a['cpu_ms_at_cal_134'])}, b {_value(b['cpu_ms_at_cal_134'])} ms/order; "
            f"round trips SELECT 1 / PING (µs): a {_value(a['select1_us'])} / {_value(a['redis_ping_us'])}, "
            f"b {_value(b['select1_us'])} / {_value(b['redis_ping_us'])}."
        )
    return "\n".join(lines) + "\n"


def _median(values: Sequence[float]) -> float | None:
    return round(statistics.median(values), 3) if values else None


def machine_line(machine: dict[str, Any]) -> str:
    return (
        f"{machine.get('cpu_model', 'unknown CPU')}, {machine['cpus']} CPUs, "
        f"{machine.get('memory_gb', '?')} GB, {machine['platform']}, Python {machine['python']}"
    )


def _series(runs: Sequence[dict[str, Any]]) -> dict[tuple[str, float], list[dict[str, Any]]]:
    series: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for result in sorted(runs, key=lambda r: r["options"]["robots"]):
        series.setdefault((result["label"], result["options"]["delay"]), []).append(result)
    return series


def _order(result: dict[str, Any]) -> tuple[str, str, float, int]:
    options = result["options"]
    return (result["mode"], result["label"], options["delay"], options["robots"])


def _settings(options: dict[str, Any]) -> str:
    missions = (
        f"K={options['nodes']} route nodes per mission, queue Q={options['queue']}, "
        f"delay {options['delay']} s, start phase {_start_rate(options)}, "
        if options["mode"] == "run"
        else "no missions, "
    )
    return f"{missions}state {options['state_hz']} Hz, warm-up {options['warmup']} s"


def _start_rate(options: dict[str, Any]) -> str:
    rate = options.get("start_rate", 0.0)  # results written before the option existed: all at once
    return f"{rate:g} missions/s" if rate else "all at once"


def _server_cpu(result: dict[str, Any], key: str) -> float:
    return round(sum(usage[key] for group, usage in result["cpu"].items() if group != GENERATOR), 3)


def _latency(summary: dict[str, Any], *keys: str) -> str:
    return " / ".join(_value(summary[key]) for key in keys)


def _value(value: Any) -> str:
    return "-" if value is None else str(value)


def _signed(value: float | None) -> str:
    return "-" if value is None else f"{value:+g}"


def _nan(value: float | None) -> float:
    """None (a slice without steps) as a gap in a line."""
    return math.nan if value is None else value


def _pyplot() -> Any:
    """matplotlib's pyplot without a display; imported only when plotting (it is slow to import)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.report", description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="+", type=Path, help="result JSON files of bench.fleet")
    parser.add_argument("--output", type=Path, default=Path("bench"), help="directory for <name>.md/.png")
    parser.add_argument("--name", default="latest", help="file name (without extension)")
    args = parser.parse_args(argv)
    results = [json.loads(path.read_text()) for path in args.results]
    table, image = write_summary(results, args.output, args.name)
    sys.stdout.write(table.read_text())
    print(f"wrote {table} and {image}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
