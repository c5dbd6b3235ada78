"""Settings from the environment: a malformed number stops the process at start with the variable's name,
not a bare error from int() that leaves the operator to guess which of 70 variables it was."""

import os
import subprocess
import sys

import pytest

from tests.deploy.layout import ROOT


@pytest.mark.parametrize(
    ("variable", "value", "message"),
    [
        ("FLEET_NOTIFY_BACKOFF_SECONDS", "0.5", "must be a whole number, not '0.5'"),
        ("FLEET_ORDER_RESEND_SECONDS", "soon", "must be a number, not 'soon'"),
    ],
)
def test_a_malformed_number_names_its_variable(variable: str, value: str, message: str) -> None:
    env = {**os.environ, variable: value, "FLEET_SECRET_KEY": "x"}
    done = subprocess.run(
        [sys.executable, "-c", "import fleet.settings"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.returncode != 0
    assert f"{variable} {message}" in done.stderr


def test_numbers_from_the_environment_are_read() -> None:
    env = {**os.environ, "FLEET_NOTIFY_BACKOFF_SECONDS": "3", "FLEET_ORDER_RESEND_SECONDS": "2.5"}
    env["FLEET_SECRET_KEY"] = "x"
    check = (
        "from fleet import settings as s; print(s.NOTIFY_BACKOFF_SECONDS, s.DISPATCH_ORDER_RESEND_SECONDS)"
    )
    done = subprocess.run(
        [sys.executable, "-c", check], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.stdout.split() == ["3", "2.5"], done.stderr
