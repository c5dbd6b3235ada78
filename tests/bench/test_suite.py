"""`bench.suite`: the stack it measures is the one `deploy/Procfile` deploys."""

import shlex
from pathlib import Path

from bench.suite import api_command

PROCFILE = Path(__file__).resolve().parents[2] / "deploy" / "Procfile"


def _comparable(argv: list[str]) -> list[str]:
    """`argv` without what may differ between the two: where granian is, its address, its access log."""
    comparable, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg in ("--host", "--port"):
            skip = True
        elif arg != "--access-log":
            comparable.append("granian" if arg.endswith("/granian") else arg)
    return comparable


def test_the_suite_runs_the_api_as_the_procfile_does() -> None:
    """Niceness, workers and threads: a figure measured with other settings would describe another API."""
    lines = dict(line.split(": ", 1) for line in PROCFILE.read_text().splitlines() if line.strip())

    assert _comparable(api_command(5000)) == _comparable(shlex.split(lines["api"]))
