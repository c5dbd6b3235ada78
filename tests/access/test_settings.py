"""What the processes refuse or warn about at start: the built-in secret key outside debug mode, and the
open API (FLEET_API_AUTH=off)."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PRINT_KEY = "import fleet.settings as s; print(s.SECRET_KEY)"


def run(code: str, tmp_path: Path, **env: str) -> subprocess.CompletedProcess[str]:
    """`code` in a fresh interpreter, with no FLEET_ or DJANGO_ variable but `env`, and no local key file
    (FLEET_LOCAL_DIR is an empty directory unless the test puts one there)."""
    inherited = {k: v for k, v in os.environ.items() if not k.startswith(("FLEET_", "DJANGO_"))}
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env={**inherited, "PYTHONPATH": str(ROOT), "FLEET_LOCAL_DIR": str(tmp_path), **env},
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_development_key_is_refused_outside_debug_mode(tmp_path):
    done = run(PRINT_KEY, tmp_path, FLEET_DEBUG="0")

    assert done.returncode != 0
    assert "ImproperlyConfigured: No secret key: set FLEET_SECRET_KEY" in done.stderr


def test_a_set_key_is_used(tmp_path):
    done = run(PRINT_KEY, tmp_path, FLEET_DEBUG="0", FLEET_SECRET_KEY="k" * 50)

    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "k" * 50


def test_the_local_key_make_run_generated_is_used(tmp_path):
    (tmp_path / "secret-key").write_text("local-" + "x" * 44 + "\n")

    done = run(PRINT_KEY, tmp_path, FLEET_DEBUG="0")

    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "local-" + "x" * 44


def test_debug_mode_may_use_the_development_key(tmp_path):
    done = run(PRINT_KEY, tmp_path, FLEET_DEBUG="1")

    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "insecure-development-key-change-me-in-production"


def test_the_api_process_warns_at_start_when_auth_is_off(tmp_path):
    off = run("import fleet.asgi", tmp_path, FLEET_SECRET_KEY="k" * 50, FLEET_API_AUTH="off")
    on = run("import fleet.asgi", tmp_path, FLEET_SECRET_KEY="k" * 50)

    assert off.returncode == 0 and on.returncode == 0, off.stderr + on.stderr
    assert "WARNING fleet.api: FLEET_API_AUTH is off" in off.stderr
    assert "FLEET_API_AUTH" not in on.stderr
