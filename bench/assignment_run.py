"""One assignment run on a burst, against PostgreSQL: N robots free on a grid, N unbound missions posted
through the service at random points of the same map, then `missions.services.missions_assign` (its two
reads, `dispatch.assignment.assign`, the binding transaction) timed. Step and assignment requests are not
queued (no Celery needed); the run's robots and missions, `assignment-bench-*`, are removed after it.

    .venv/bin/python -m bench.assignment_run [--size 1000] [--repeats 3]

Against the database of FLEET_DB_NAME (`make run`'s, or any migrated one). Results: bench/HISTORY.md,
"Assignment".
"""

import argparse
import os
import random
import statistics
import time

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

from django.utils import timezone  # noqa: E402

from access.choices import command_actor  # noqa: E402
from kit import wake  # noqa: E402
from missions.models import Mission  # noqa: E402
from missions.services import mission_create, missions_assign  # noqa: E402
from robots.models import Robot  # noqa: E402

PREFIX = "assignment-bench"
SPACING_M = 5.0  # between two robots of the grid
SEED = 41


def _clear() -> None:
    Mission.objects.filter(name__startswith=PREFIX).delete()
    Robot.objects.filter(name__startswith=PREFIX).delete()


def _burst(size: int, rng: random.Random) -> None:
    side = max(1, round(size**0.5))
    now = timezone.now()
    Robot.objects.bulk_create(
        Robot(
            name=f"{PREFIX}-r{index}",
            serial_number=f"{PREFIX}-r{index}",
            online=True,
            battery_level=80.0,
            pose_x=SPACING_M * (index % side),
            pose_y=SPACING_M * (index // side),
            pose_map_id="map",
            last_state_at=now,
        )
        for index in range(size)
    )
    actor = command_actor("assignment_run")
    for index in range(size):
        x, y = rng.uniform(0, SPACING_M * side), rng.uniform(0, SPACING_M * side)
        waypoint = {"x": x, "y": y, "map_id": "map"}
        route = {"route": {"waypoints": [waypoint]}}
        mission_create(actor=actor, name=f"{PREFIX}-m{index}", prefix=None, spec={"mission_tree": [route]})


def run(size: int, repeats: int) -> tuple[float, float]:
    """The median wall and CPU seconds of `repeats` runs binding `size` missions to `size` robots."""
    rng = random.Random(SEED)
    walls, cpus = [], []
    for _ in range(repeats):
        _clear()
        _burst(size, rng)
        wall, cpu = time.perf_counter(), time.process_time()
        bound = missions_assign().bound
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
        assert len(bound) == size, f"{len(bound)} of {size} bound"
    _clear()
    return statistics.median(walls), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=1000, help="robots and missions, N each")
    parser.add_argument("--repeats", type=int, default=3)
    options = parser.parse_args()
    # What the run asks for is not queued here.
    wake.install(lambda names: None, lambda defer_while_busy: None, lambda: None)
    wall, cpu = run(options.size, options.repeats)
    print(
        f"{options.size} robots x {options.size} missions: every mission bound in one run of "
        f"{wall * 1e3:.0f} ms wall (median of {options.repeats}), {cpu * 1e3:.0f} ms CPU of this process "
        f"({cpu / options.size * 1e3:.2f} ms per mission)"
    )


if __name__ == "__main__":
    main()
