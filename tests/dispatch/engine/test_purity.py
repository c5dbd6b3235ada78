"""The pure modules stay pure: importing the vocabulary, the engine, the dispatch step, the assignment or
the VDA 5050 package pulls in neither Django, paho, Redis nor Celery (numpy and SciPy are pure enough)."""

import subprocess
import sys

import pytest

CHECK = """
import sys
import {module}
print(sorted({{m.split(".")[0] for m in sys.modules}} & {{"django", "paho", "redis", "celery"}}))
"""


@pytest.mark.parametrize(
    "module",
    [
        "dispatch.vocabulary",
        "dispatch.engine",
        "dispatch.step",
        "dispatch.instant",
        "dispatch.records",
        "dispatch.held",
        "dispatch.assignment",
        "dispatch.stations",
        "dispatch.sent",
        "dispatch.faults",
        "vda5050",
        "vda5050.codec",
        "vda5050.models",
        "vda5050.orders",
        "vda5050.state",
        "vda5050.topics",
    ],
)
def test_pure_module_imports_no_framework(module):
    # A fresh interpreter: this test process already has Django loaded by pytest-django.
    check = CHECK.format(module=module)
    done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
