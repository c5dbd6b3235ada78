"""PostgreSQL's work per mission on the dispatch path, in-process: each mission created by the service the API
calls, started by a step, its order taken (the bridge's flush of taken orders, one statement for all
robots) and ended by the next step, which starts the robot's next mission, as at saturation. Counts what
does not depend on the machine's speed (write-ahead log bytes, mission UPDATEs and the share of them
PostgreSQL made HOT, change-feed rows) and, beside them, the CPU of the connection's backend and of this
process. Run on a database and a Redis database of their own:

    FLEET_DB_NAME=md_pg_cost FLEET_REDIS_URL=redis://127.0.0.1:6379/5 FLEET_SECRET_KEY=... \\
        .venv/bin/python -m bench.pg_cost --missions 600

The WAL figure is the server's: nothing else may write to PostgreSQL meanwhile. To compare two versions,
migrate a database from each tree and alternate the two runs. Results: bench/HISTORY.md, "What the feed
records".
"""

import argparse
import os
import time
import uuid
from dataclasses import dataclass

import django

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")
django.setup()

import orjson  # noqa: E402
from django.db import connection  # noqa: E402

from bench.measure import cpu_speed_ms, process_sample  # noqa: E402
from bench.robot import FakeRobot, utc_now  # noqa: E402
from dispatch.held import state_digest  # noqa: E402
from missions.robot_step import robot_step  # noqa: E402
from missions.services import (  # noqa: E402
    mission_create,
    mission_orders_accepted,
)
from robots import livestate  # noqa: E402
from robots.models import Robot  # noqa: E402
from robots.services import robot_create  # noqa: E402
from vda5050.codec import parse_state  # noqa: E402
from vda5050.topics import Topic  # noqa: E402

ACTOR = "bench-pg-cost"
ROUTE = {"name": "r", "route": {"waypoints": [{"x": 5.0, "y": 6.0, "theta": 0.0, "map_id": "map"}]}}


@dataclass
class Counters:
    wal_lsn: str
    mission_updates: int
    mission_hot_updates: int
    changes: int
    backend_cpu_s: float


class Fleet:
    """Robots driven through the step's own path, their states stored in Redis as the bridge stores them."""

    def __init__(self, robots: int) -> None:
        run = uuid.uuid4().hex[:6]
        self.robots: dict[str, FakeRobot] = {}
        self.missions = 0
        for index in range(robots):
            name = f"pgcost-{run}-{index}"
            robot_create(actor=ACTOR, name=name, prefix=None, spec={})
            Robot.objects.filter(name=name).update(online=True)  # as the bridge's flush has it
            self.robots[name] = FakeRobot(serial=name, manufacturer="", topic_prefix="", x=0.0, y=0.0)
            self._store_state(name)
            self._create_mission(name)
            self._create_mission(name)

    def round(self) -> int:
        """Step every robot (ending its mission, if any, and starting the next) and have it take the order;
        flush the taken orders in one statement, as the bridge does once a second; have every robot finish
        and queue one more mission. Returns the number of missions started."""
        taken = {}
        for name, robot in self.robots.items():
            wire = robot_step(name=name).wire
            livestate.claim_published(name, [(m.topic.value, m.header_id) for m in wire])  # as publishing
            [order] = [orjson.loads(m.payload) for m in wire if m.topic is Topic.ORDER]
            robot.accept(order)
            self._store_state(name)
            taken[name] = (order["orderId"], order["orderUpdateId"])
        mission_orders_accepted(orders=taken)
        for name, robot in self.robots.items():
            robot.finish()
            self._store_state(name)
            self._create_mission(name)
        return len(taken)

    def _create_mission(self, name: str) -> None:
        self.missions += 1
        spec = {"robot": name, "mission_tree": [ROUTE]}
        mission_create(actor=ACTOR, name=f"{name}-m{self.missions}", prefix=None, spec=spec)

    def _store_state(self, name: str) -> None:
        robot = self.robots[name]
        payload = robot.state(utc_now())
        pipe = livestate.client().pipeline(transaction=False)
        livestate.store_state(
            pipe,
            name=name,
            payload=payload,
            timestamp_ms=int(time.time() * 1000),
            header_id=robot.header_ids["state"] - 1,
            digest=state_digest(parse_state(payload)),
            arrived_at=time.time(),
        )
        livestate.execute(pipe)


def counters() -> Counters:
    """The server's WAL position and the missions table's and the feed's counts, and this connection's
    backend's CPU."""
    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_stat_force_next_flush()")  # this backend's counts, at its next commit
        cursor.execute(
            """SELECT pg_current_wal_lsn(), pg_backend_pid(), n_tup_upd, n_tup_hot_upd,
                (SELECT n_tup_ins FROM pg_stat_user_tables WHERE relname = 'changes_change')
            FROM pg_stat_user_tables WHERE relname = 'missions_mission'"""
        )
        lsn, pid, updates, hot, changes = cursor.fetchone()
    backend = process_sample(pid)  # the server runs on this machine
    assert backend is not None
    return Counters(lsn, updates, hot, changes, backend.cpu_seconds)


def wal_bytes(before: str, after: str) -> int:
    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_wal_lsn_diff(%s, %s)", [after, before])
        return int(cursor.fetchone()[0])


@dataclass
class PerMission:
    wal_bytes: float
    mission_updates: float
    hot_share: float
    feed_rows: float
    backend_cpu_ms: float
    client_cpu_ms: float


def measure(*, missions: int, robots: int) -> PerMission:
    """Run at least `missions` missions through `robots` new robots; PostgreSQL's work per mission."""
    fleet = Fleet(robots)
    fleet.round()  # each robot's first mission started, the tables' first pages written
    before, client_cpu = counters(), time.process_time()
    done = 0
    while done < missions:
        done += fleet.round()
    client_cpu = time.process_time() - client_cpu
    after = counters()
    updates = after.mission_updates - before.mission_updates
    return PerMission(
        wal_bytes=wal_bytes(before.wal_lsn, after.wal_lsn) / done,
        mission_updates=updates / done,
        hot_share=(after.mission_hot_updates - before.mission_hot_updates) / max(updates, 1),
        feed_rows=(after.changes - before.changes) / done,
        backend_cpu_ms=(after.backend_cpu_s - before.backend_cpu_s) / done * 1e3,
        client_cpu_ms=client_cpu / done * 1e3,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--missions", type=int, default=600)
    parser.add_argument("--robots", type=int, default=20)
    args = parser.parse_args()
    cost = measure(missions=args.missions, robots=args.robots)
    print(
        f"{args.robots} robots: WAL {cost.wal_bytes:.0f} B per mission; {cost.mission_updates:.2f} mission"
        f" UPDATEs per mission, {cost.hot_share:.0%} HOT; {cost.feed_rows:.2f} feed rows per mission;"
        f" CPU per mission: PostgreSQL backend {cost.backend_cpu_ms:.2f} ms, this process"
        f" {cost.client_cpu_ms:.2f} ms; calibration {cpu_speed_ms():.0f} ms"
    )


if __name__ == "__main__":
    main()
