"""The benchmark's generators as the tests run them: `python -m bench.<module>` in a process of its own."""

import subprocess

from tests.e2e.conftest import PYTHON, ROOT

GENERATOR_TIMEOUT = 180  # s; generous, the machine is shared


def run_generator(module: str, *args: str) -> None:
    """`python -m <module> <args>` from the project's root; a failure fails the test with its stderr."""
    finished = subprocess.run(
        [PYTHON, "-m", module, *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=GENERATOR_TIMEOUT,
        check=False,
    )
    assert finished.returncode == 0, finished.stderr[-3000:]
