"""What the deployment files are checked against: deploy/Procfile's processes, the files' paths, the tools."""

import re
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
# Processes that only exist for demos: in Compose's `simulator` profile, never in Kubernetes.
DEMO_PROCESSES = {"simulator"}


def procfile_processes() -> list[str]:
    """The process names of deploy/Procfile, in order: the image's roles and the services to deploy."""
    text = (DEPLOY / "Procfile").read_text()
    return re.findall(r"^([a-z_]+):", text, flags=re.MULTILINE)


def tool(name: str, how: str) -> str:
    """The path of the command-line tool `name` (on the PATH or in the test's own virtual environment), or a
    skip that says how to install it."""
    path = shutil.which(name) or shutil.which(name, path=str(Path(sys.executable).parent))
    if path is None:
        pytest.skip(f"{name} not found: {how}")
    return path
