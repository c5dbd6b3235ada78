"""The short fault-injection run in every `make test`: about 10 robots, 100 missions, 60 s of random faults
on a private stack, then a quiet phase until every mission ended (at most 120 s), then the checks.

The seed changes from run to run unless FLEET_FAULT_SEED is set; it is printed at the start and named in
every failure, so `FLEET_FAULT_SEED=<seed> make test PYTEST_ARGS=tests/faults` replays a run's faults
(`python -m tests.faults --seed <seed> ...` runs the long version).
"""

from pathlib import Path

import pytest

from tests.faults.runner import SEED_ENV, RunConfig, run, seed_from_env

pytestmark = [pytest.mark.faults, pytest.mark.e2e]


@pytest.mark.timeout(480)
def test_short_fault_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    seed = seed_from_env()
    logs = tmp_path / "logs"
    with capsys.disabled():
        print(f"\nfault suite seed {seed} ({SEED_ENV}={seed} replays it); logs in {logs}", flush=True)
    config = RunConfig(
        seed=seed, robots=10, missions=100, fault_seconds=60, quiet_seconds=120, keep_logs=logs
    )
    outcome = run(config)
    summary = outcome.summary()
    with capsys.disabled():
        print(summary, flush=True)
    assert outcome.ok, summary
