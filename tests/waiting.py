"""Waiting in tests for what another thread or process does: poll, never sleep a fixed time."""

import time
from collections.abc import Callable
from typing import Any

import pytest

WAIT_SECONDS = 60.0  # generous: the machine is shared; nothing asserts on durations


def wait_for(condition: Callable[[], Any], message: str = "", *, timeout: float = WAIT_SECONDS) -> Any:
    """Poll until `condition` returns something truthy and return it; fail the test with `message` else."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.02)
    pytest.fail(f"timed out waiting for {message or condition}")
