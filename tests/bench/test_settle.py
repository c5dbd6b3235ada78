"""The generator waits for the server to work off the fleet's arrival before it measures anything."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import uuid

from bench.fleet import SETTLED_READINGS, Bench
from bench.fleet_options import Options


def test_the_start_waits_until_the_servers_processes_are_quiet() -> None:
    marker = f"settle-{uuid.uuid4().hex}"
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass", marker])  # a server still at work
    # A threshold far below a spinning process's share of a core even on a loaded machine (a full suite and a
    # benchmark beside it once left it under half a core, and the wait ended early): quiet means stopped.
    options = Options(robots=1, settle_cores=0.05, online_timeout=30, process_groups={"server": marker})

    async def settle() -> float:
        bench = Bench(options)
        asyncio.get_running_loop().call_later(2.5, busy.kill)
        await bench.wait_settled()
        return bench.settle_seconds

    try:
        settled = asyncio.run(settle())
    finally:
        busy.kill()
        busy.wait()
    # Busy readings until the kill at 2.5 s, then SETTLED_READINGS quiet ones (the one spanning the kill
    # may be either); the upper bound only says it did not run to online_timeout.
    assert 2 + SETTLED_READINGS <= settled < options.online_timeout


def test_a_server_whose_processes_cannot_be_seen_counts_as_settled_at_once() -> None:
    options = Options(robots=1, process_groups={"server": f"no-such-process-{uuid.uuid4().hex}"})

    async def settle() -> float:
        bench = Bench(options)
        await bench.wait_settled()
        return bench.settle_seconds

    assert asyncio.run(settle()) < SETTLED_READINGS + 1
