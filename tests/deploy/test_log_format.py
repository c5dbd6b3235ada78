"""FLEET_LOG_FORMAT: `json` writes one JSON object per record on stdout; anything but plain or json is
refused."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LOG_AN_ERROR = """
import logging, django
django.setup()
try:
    1 / 0
except ZeroDivisionError:
    logging.getLogger("fleet.demo").exception("robot %s lost", "carter01")
"""


def run(code: str, **env: str) -> subprocess.CompletedProcess[str]:
    """`code` in a fresh interpreter with the production settings and no FLEET_ variable but `env`."""
    inherited = {k: v for k, v in os.environ.items() if not k.startswith(("FLEET_", "DJANGO_"))}
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env={
            **inherited,
            "PYTHONPATH": str(ROOT),
            "DJANGO_SETTINGS_MODULE": "fleet.settings",
            "FLEET_SECRET_KEY": "k" * 50,
            **env,
        },
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_json_lines_on_stdout():
    done = run(LOG_AN_ERROR, FLEET_LOG_FORMAT="json")

    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    (line,) = done.stdout.splitlines()
    record = json.loads(line)
    assert record["level"] == "ERROR"
    assert record["logger"] == "fleet.demo"
    assert record["message"] == "robot carter01 lost"
    assert "ZeroDivisionError" in record["exc_info"]
    assert record["time"].endswith("+00:00")


def test_plain_text_on_stderr_by_default():
    done = run(LOG_AN_ERROR)

    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    assert "ERROR fleet.demo: robot carter01 lost" in done.stderr.splitlines()[0]


def test_an_unknown_format_is_refused():
    done = run("import django; django.setup()", FLEET_LOG_FORMAT="xml")

    assert done.returncode != 0
    assert "FLEET_LOG_FORMAT must be plain or json, not 'xml'" in done.stderr
