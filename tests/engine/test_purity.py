"""The engine is pure: importing it pulls in neither Django, paho nor Redis."""

import subprocess
import sys

CHECK = """
import sys
import missions.engine
print(sorted({m.split(".")[0] for m in sys.modules} & {"django", "paho", "redis", "celery"}))
"""


def test_engine_imports_no_framework():
    # A fresh interpreter: this test process already has Django loaded by pytest-django.
    done = subprocess.run([sys.executable, "-c", CHECK], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
