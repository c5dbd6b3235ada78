"""A ``bench.fleet`` run's settings (`Options`) and the command line that makes them (``build_parser``,
``options_from``), which ``bench.watchers`` extends."""

from __future__ import annotations

import argparse
import os
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from bench import measure

RUN, IDLE, BURST = "run", "idle", "burst"  # burst: --unbound missions posted at once, then no more


@dataclass(frozen=True)
class Options:
    """One run's settings (the command line's options; see bench/README.md)."""

    mode: str = RUN
    base_url: str = "http://127.0.0.1:5000"
    api_token: str | None = None  # sent as Authorization: Bearer; the reference needs none
    mqtt_host: str = "127.0.0.1"
    mqtt_port: int = 1883
    mqtt_prefix: str = "uagv/v2/RobotCompany"
    mqtt_username: str | None = None
    mqtt_password: str | None = None
    mqtt_tls: bool = False
    mqtt_ca_file: str | None = None
    robots: int = 10
    nodes: int = 5
    queue: int = 2
    delay: float = 0.0
    start_rate: float = 0.0  # missions/s in the start phase; 0: all at once
    state_hz: float = 1.0
    duration: float = 30.0
    warmup: float = 5.0
    sample_every: float = 30.0
    mission_timeout: float = 3600.0
    robots_per_connection: int = 250
    http_concurrency: int = 8
    online_timeout: float = 120.0
    settle_cores: float = field(default_factory=lambda: 0.3 * (os.cpu_count() or 1))
    run_id: str = field(default_factory=lambda: uuid.uuid4().hex[:6])
    label: str = ""
    output: Path = Path("bench/results")
    cleanup: bool = True
    probe_postgres: str | None = None  # conninfo for the round-trip probe at the run's start
    probe_redis: str | None = None  # Redis URL for the round-trip probe at the run's start
    process_groups: dict[str, str] = field(default_factory=lambda: dict(measure.DEFAULT_PROCESS_GROUPS))
    unbound: bool = False  # missions without a robot (issue 41): assignment picks one
    seed: int = 41  # --unbound: robots' places and missions' destinations on the map

    @property
    def manufacturer(self) -> str:
        return self.mqtt_prefix.rsplit("/", 1)[-1]

    @property
    def name_prefix(self) -> str:
        return f"bench-{self.run_id}"


def build_parser() -> argparse.ArgumentParser:
    defaults = Options()
    parser = argparse.ArgumentParser(
        prog="python -m bench.fleet",
        description="Load Mission Dispatch with fast fake VDA 5050 robots and measure it (bench/README.md).",
    )
    parser.add_argument(
        "--mode",
        choices=(RUN, IDLE, BURST),
        default=RUN,
        help="run: missions; idle: states only; burst (--unbound): one mission per robot at once, no more",
    )
    parser.add_argument(
        "--unbound",
        action="store_true",
        help="missions without a robot (assignment picks one), robots and destinations spread over one map",
    )
    parser.add_argument("--seed", type=int, default=defaults.seed, help="--unbound: places on the map")
    parser.add_argument("--base-url", default=defaults.base_url, help="the server's REST API")
    parser.add_argument(
        "--api-token",
        default=os.environ.get("FLEET_API_TOKEN"),
        help="bearer token for the REST API (python manage.py api_token create bench; default: "
        "$FLEET_API_TOKEN); the reference needs none",
    )
    parser.add_argument("--mqtt-host", default=defaults.mqtt_host)
    parser.add_argument("--mqtt-port", type=int, default=defaults.mqtt_port)
    parser.add_argument(
        "--mqtt-prefix",
        default=defaults.mqtt_prefix,
        help="interfaceName/majorVersion/manufacturer; robots use <prefix>/<robot name>/<topic>",
    )
    parser.add_argument("--mqtt-username", default=None)
    parser.add_argument("--mqtt-password", default=None)
    parser.add_argument("--mqtt-tls", action="store_true", help="connect to the broker over TLS")
    parser.add_argument("--mqtt-ca-file", default=None, help="CA certificate(s) (default: the system's)")
    parser.add_argument("--robots", type=int, default=defaults.robots, help="fleet size N")
    parser.add_argument(
        "--sweep", default="", help="comma-separated fleet sizes, one run each (overrides --robots)"
    )
    parser.add_argument(
        "--nodes", type=int, default=defaults.nodes, help="route nodes (orders) per mission K"
    )
    parser.add_argument("--queue", type=int, default=defaults.queue, help="missions kept queued per robot Q")
    parser.add_argument("--delay", type=float, default=defaults.delay, help="s a robot takes per order")
    parser.add_argument(
        "--start-rate",
        type=float,
        default=defaults.start_rate,
        help="missions/s posted in the start phase, as robots fall idle in a working fleet (0: all at once)",
    )
    parser.add_argument(
        "--state-hz", type=float, default=defaults.state_hz, help="periodic states per robot per s"
    )
    parser.add_argument("--duration", type=float, default=defaults.duration, help="s of measurement window")
    parser.add_argument("--warmup", type=float, default=defaults.warmup, help="s before the window")
    parser.add_argument(
        "--sample-every",
        type=_positive,
        default=defaults.sample_every,
        help="s per slice of the window's time series (RSS, CPU, step latency, orders/s)",
    )
    parser.add_argument(
        "--mission-timeout", type=float, default=defaults.mission_timeout, help="s, per mission"
    )
    parser.add_argument("--robots-per-connection", type=int, default=defaults.robots_per_connection)
    parser.add_argument("--http-concurrency", type=int, default=defaults.http_concurrency)
    parser.add_argument("--online-timeout", type=float, default=defaults.online_timeout)
    parser.add_argument(
        "--settle-cores",
        type=float,
        default=defaults.settle_cores,
        help="server cores below which it has worked off the fleet's arrival (default: 0.3 x CPU count)",
    )
    parser.add_argument("--run-id", default=None, help="robot names are bench-<run id>-<i> (default: random)")
    parser.add_argument("--label", default="", help="names the run in reports (e.g. the server under test)")
    parser.add_argument("--output", type=Path, default=defaults.output, help="directory for JSON + Markdown")
    parser.add_argument(
        "--cleanup",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="delete the robots and clear their retained messages at the end",
    )
    parser.add_argument(
        "--probe-postgres",
        default=None,
        metavar="CONNINFO",
        help="measure SELECT 1 round trips on this PostgreSQL database at the run's start",
    )
    parser.add_argument(
        "--probe-redis", default=None, metavar="URL", help="measure Redis PING round trips at the run's start"
    )
    parser.add_argument(
        "--proc",
        action="append",
        default=[],
        metavar="GROUP=REGEX",
        help="server process group by command-line regex; replaces a default group or adds one "
        f"(defaults: {', '.join(f'{k}={v}' for k, v in measure.DEFAULT_PROCESS_GROUPS.items())})",
    )
    parser.add_argument("--log-level", choices=("DEBUG", "INFO", "WARNING", "ERROR"), default="INFO")
    return parser


def options_from(args: argparse.Namespace, robots: int, sweep: bool = False) -> Options:
    """Options of one run; in a sweep a given run id gets the fleet size appended (names stay unique)."""
    groups = dict(measure.DEFAULT_PROCESS_GROUPS)
    for spec in args.proc:
        group, separator, pattern = spec.partition("=")
        if not separator or not group:
            raise SystemExit(f"--proc expects GROUP=REGEX, got {spec!r}")
        groups[group] = pattern
    values = {
        key: value
        for key, value in vars(args).items()
        if key not in {"sweep", "proc", "log_level", "robots", "run_id"}
    }
    run_id = args.run_id or uuid.uuid4().hex[:6]
    if args.run_id and sweep:
        run_id = f"{args.run_id}-{robots}"
    if args.mode == BURST and not args.unbound:
        raise SystemExit("--mode burst needs --unbound")
    return Options(**values, robots=robots, run_id=run_id, process_groups=groups)


def _positive(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value
