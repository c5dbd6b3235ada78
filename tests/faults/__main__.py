"""`python -m tests.faults`: the long fault-injection run (see tests/faults/runner.py); exit 1 on failure.

    .venv/bin/python -m tests.faults --seed 42 --robots 20 --missions 300 --fault-seconds 180 \
        --quiet-seconds 300 --keep-logs /tmp/faults-42
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

from tests.faults.runner import SEED_ENV, RunConfig, run, seed_from_env


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tests.faults",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--seed", type=int, default=None, help=f"default: {SEED_ENV}, else random")
    parser.add_argument("--robots", type=int, default=20)
    parser.add_argument("--missions", type=int, default=300)
    parser.add_argument("--fault-seconds", type=float, default=180.0)
    parser.add_argument(
        "--quiet-seconds",
        type=float,
        default=300.0,
        help="bound on the quiet phase (it ends once all missions did)",
    )
    parser.add_argument("--speed", type=float, default=3.0, help="simulated robots' speed (m/s)")
    parser.add_argument(
        "--keep-logs", type=Path, default=None, help="copy the processes' logs and recordings here"
    )
    args = parser.parse_args(argv)
    if args.robots < 1 or args.missions < 1 or args.fault_seconds < 0 or args.quiet_seconds <= 0:
        parser.error("--robots and --missions must be >= 1, --fault-seconds >= 0, --quiet-seconds > 0")
    config = RunConfig(
        seed=args.seed if args.seed is not None else seed_from_env(),
        robots=args.robots,
        missions=args.missions,
        fault_seconds=args.fault_seconds,
        quiet_seconds=args.quiet_seconds,
        speed=args.speed,
        keep_logs=args.keep_logs,
    )
    print(f"fault suite seed {config.seed} (replay with --seed {config.seed})", flush=True)
    # SIGTERM ends the run like Ctrl-C: the stack is torn down on the way out.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    outcome = run(config)
    print(outcome.summary(max_problems=1000), flush=True)
    return 0 if outcome.ok else 1


if __name__ == "__main__":
    sys.exit(main())
