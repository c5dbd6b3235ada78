"""Server processes a benchmark starts from a source tree (this checkout or another one, to compare
versions side by side) and stops at its end."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def running(
    commands: Mapping[str, list[str]], code: Path, env: Mapping[str, str], logs: Path
) -> Iterator[dict[str, subprocess.Popen[bytes]]]:
    """Each command (name -> argv) run from source tree `code` (its working directory and first on the
    import path), its output in `logs/<name>.log`; each stopped with its process group (a server's
    workers) at the end. A process that exited before then fails the run."""
    logs.mkdir(parents=True, exist_ok=True)
    env = {**env, "PYTHONPATH": str(code)}
    started = {
        name: subprocess.Popen(
            argv,
            cwd=code,
            env=env,
            stdout=(logs / f"{name}.log").open("wb"),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        for name, argv in commands.items()
    }
    try:
        yield started
        exited = [name for name, process in started.items() if process.poll() is not None]
        if exited:
            raise RuntimeError(f"processes exited during the run: {exited}; see {logs}")
    finally:
        for process in started.values():
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in started.values():
            process.wait(timeout=60)
