"""`fleet.asgi` and `fleet.wsgi`: what the API's server processes load."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import gc, json, sys
import fleet.{module}
print(json.dumps({
    "frozen": gc.get_freeze_count(),
    "young": len(gc.get_objects()),
    "loaded": [m for m in ("missions.api.serializers", "robots.api.views") if m in sys.modules],
}))
"""


@pytest.mark.parametrize("module", ["asgi", "wsgi"])
def test_the_api_process_loads_its_views_and_freezes_what_it_loaded(module: str) -> None:
    """Frozen objects are out of the collector's sight: its full collections no longer walk all of Django."""
    probe = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", PROBE.replace("{module}", module)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    found = json.loads(probe.stdout)

    assert found["loaded"] == ["missions.api.serializers", "robots.api.views"]
    assert found["frozen"] > 50_000  # Django, DRF and the apps
    assert found["young"] < found["frozen"] / 100
