"""A/B micro-benchmark of the change feed's cost on the hot writes: the bridge's status flush (1,000 robots
in one statement) and the step's mission UPDATE (one per transaction), with the feed's triggers enabled
and disabled, alternating. Run on a database of its own (it creates and deletes its rows and their feed
rows):

    FLEET_DB_NAME=mission_dispatch_bench .venv/bin/python -m bench.changes_ab

Results and the machine's calibration figure: bench/HISTORY.md, "Change feed".
"""

import argparse
import os
import statistics
import time

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

from django.db import connection, transaction  # noqa: E402
from django.utils import timezone  # noqa: E402

from bench.measure import CALIBRATION_ITERATIONS, _calibration_work  # noqa: E402
from changes.models import Change  # noqa: E402
from missions.models import Mission  # noqa: E402
from missions.robot_step import _mission_update_sql  # noqa: E402
from missions.rows import mission_db_values  # noqa: E402
from robots.models import Robot  # noqa: E402
from robots.status import robot_status_write  # noqa: E402

PREFIX = "changes-ab-"
TRIGGERS = [
    ("robots_robot", "robots_robot_changes_update"),
    ("missions_mission", "missions_mission_changes_update"),
]


def _triggers(enabled: bool) -> None:
    with connection.cursor() as cursor:
        for table, trigger in TRIGGERS:
            cursor.execute(f"ALTER TABLE {table} {'ENABLE' if enabled else 'DISABLE'} TRIGGER {trigger}")


def _flush(robots: list[str], round_: int) -> float:
    rows = [(float(i % 7 + round_), float(round_ % 100), name) for i, name in enumerate(robots)]
    started = time.perf_counter()
    robot_status_write(columns=("pose_x", "battery_level"), rows=rows)
    return time.perf_counter() - started


def _steps(missions: list[str], round_: int) -> float:
    sql = _mission_update_sql(("current_node", "node_status", "updated_at"))
    started = time.perf_counter()
    for name in missions:
        values = {
            "current_node": round_ % 4,
            "node_status": {
                f"leg{i}": {"state": "RUNNING" if i == round_ % 4 else "PENDING"} for i in range(4)
            },
            "updated_at": timezone.now(),
        }
        with transaction.atomic(), connection.cursor() as cursor:
            cursor.execute(sql, [*mission_db_values(values), name])
    return (time.perf_counter() - started) / len(missions)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--missions", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=10)
    args = parser.parse_args()
    started = time.perf_counter()
    _calibration_work(CALIBRATION_ITERATIONS)
    calibration_ms = (time.perf_counter() - started) * 1000
    Robot.objects.filter(name__startswith=PREFIX).delete()
    robots = [f"{PREFIX}{i}" for i in range(args.robots)]
    Robot.objects.bulk_create([Robot(name=name, serial_number=name) for name in robots])
    waypoints = [{"x": 1, "y": 1}]
    tree = [{"name": f"leg{i}", "parent": "root", "route": {"waypoints": waypoints}} for i in range(4)]
    missions = [f"{PREFIX}m{i}" for i in range(args.missions)]
    Mission.objects.bulk_create([Mission(name=name, robot=robots[0], mission_tree=tree) for name in missions])
    results: dict[bool, dict[str, list[float]]] = {on: {"flush": [], "step": []} for on in (True, False)}
    try:
        for round_ in range(args.rounds):
            for enabled in (round_ % 2 == 0, round_ % 2 != 0):
                _triggers(enabled)
                results[enabled]["flush"].append(_flush(robots, round_))
                results[enabled]["step"].append(_steps(missions, round_))
    finally:
        _triggers(True)
        Mission.objects.filter(name__startswith=PREFIX).delete()
        Robot.objects.filter(name__startswith=PREFIX).delete()
        Change.objects.filter(name__startswith=PREFIX).delete()  # the feed rows all this wrote
    print(f"calibration work: {calibration_ms:.1f} ms (lower is faster)")
    print(f"| feed | status flush, {args.robots} robots (ms, median) | mission UPDATE + commit (ms) |")
    print("|---|---|---|")
    for enabled in (False, True):
        flush = statistics.median(results[enabled]["flush"]) * 1000
        step = statistics.median(results[enabled]["step"]) * 1000
        print(f"| {'on' if enabled else 'off'} | {flush:.1f} | {step:.3f} |")


if __name__ == "__main__":
    main()
