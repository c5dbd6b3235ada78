"""A private Mission Dispatch stack for fault injection: its own PostgreSQL cluster, Redis and Mosquitto on
free ports, and the processes of `deploy/Procfile` (API, bridge, step worker, notify worker, beat) plus a
simulator against them, each in a process group of its own with its own log file.

Only what this module started is ever signalled: the process groups of its own `Popen`s, and the postmaster
of its own data directory (through `pg_ctl`, or by the pid in that directory's `postmaster.pid`). The
machine's shared PostgreSQL, Redis and Mosquitto are never touched.
"""

from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bench.suite import api_command, api_token_create, worker_command
from simulator.config import RobotConfig, spread_robots
from tests.faults.checks import ProcessExit
from tests.private_redis import redis_server_command
from tests.server_env import SERVER_ENV

ROOT = Path(__file__).resolve().parents[2]
PYTHON = sys.executable
VENV_BIN = Path(PYTHON).parent
CELERY = str(VENV_BIN / "celery")

DB_NAME = "mission_dispatch"
MAX_RESTARTS = 5  # of a process that keeps exiting by itself


def free_ports(count: int) -> list[int]:
    """`count` distinct TCP ports of 127.0.0.1 nobody listens on now (never 5432/6379/1883: the kernel
    hands out ephemeral ports)."""
    with contextlib.ExitStack() as stack:
        sockets = [stack.enter_context(socket.socket()) for _ in range(count)]
        for sock in sockets:
            sock.bind(("127.0.0.1", 0))
        return [sock.getsockname()[1] for sock in sockets]


def free_port() -> int:
    return free_ports(1)[0]


def port_open(port: int, host: str = "127.0.0.1") -> bool:
    with contextlib.suppress(OSError), socket.create_connection((host, port), timeout=0.5):
        return True
    return False


def wait_until(condition: Callable[[], object], what: str, timeout: float = 60, period: float = 0.1) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(period)
    raise RuntimeError(f"timed out after {timeout:.0f} s waiting for {what}")


def log_tail(path: Path, lines: int = 15) -> str:
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        return ""
    return " | ".join(line.strip() for line in text.splitlines()[-lines:])


def outside_hint(tail: str) -> str:
    """What a log's end says about a shutdown signal: during a run this suite only ever sends SIGKILL, so
    a broker or Redis shutting down cleanly was signalled by a process outside it, which this suite reports
    instead of taking it for a product failure."""
    if "terminating" in tail or "Received SIGTERM" in tail or "Received SIGINT" in tail:
        return " [it was asked to shut down: a SIGTERM/SIGINT from outside this suite]"
    return ""


@dataclass
class Proc:
    """One process of ours in a process group of its own, appending to its own log file."""

    name: str
    argv: list[str]
    env: dict[str, str]
    log: Path
    cwd: Path = ROOT
    popen: subprocess.Popen[bytes] | None = None
    starts: int = 0

    def start(self) -> None:
        with self.log.open("ab") as log:
            log.write(f"=== fault suite: start #{self.starts + 1} at {time.time():.3f}\n".encode())
            log.flush()
            self.popen = subprocess.Popen(
                self.argv,
                cwd=self.cwd,
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        self.starts += 1

    def running(self) -> bool:
        """Whether the leader still runs. An ended leader is left unreaped (a zombie), so its pid, the group's
        id, cannot be reused before `kill` has signalled the group: only ever our own processes."""
        if self.popen is None or self.popen.returncode is not None:
            return False
        try:
            ended = os.waitid(os.P_PID, self.popen.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:
            return False
        return ended is None

    def signal_group(self, sig: int) -> None:
        """Signal this process's own group (its pid is the group's id: start_new_session)."""
        if self.running():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.popen.pid, sig)

    def kill(self) -> int | None:
        """SIGKILL the whole group (a worker's children too), then reap the leader; its exit code."""
        if self.popen is None:
            return None
        if self.popen.returncode is None:  # not reaped yet: the group id is still ours
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.popen.pid, signal.SIGKILL)
        return self.popen.wait(timeout=30)

    def stop(self, timeout: float = 10) -> None:
        """SIGTERM, then SIGKILL of the group if it has not ended within `timeout`."""
        if self.popen is None:
            return
        self.signal_group(signal.SIGTERM)
        deadline = time.monotonic() + timeout
        while self.running() and time.monotonic() < deadline:
            time.sleep(0.05)
        self.kill()


def _as_postgres() -> list[str]:
    """Command prefix that runs a PostgreSQL binary as the `postgres` OS user when we are root (the server
    refuses to run as root); nothing when we are not."""
    if os.geteuid() != 0:
        return []
    if shutil.which("runuser"):
        return ["runuser", "-u", "postgres", "--"]
    return ["setpriv", "--reuid=postgres", "--regid=postgres", "--init-groups", "--"]


def postgres_bin() -> Path:
    candidates = sorted(
        Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"), key=lambda p: int(p.parent.parent.name)
    )
    if candidates:
        return candidates[-1].parent
    found = shutil.which("pg_ctl")
    if found is None:
        raise RuntimeError("no PostgreSQL server binaries (pg_ctl) on this machine")
    return Path(found).parent


class Postgres:
    """A PostgreSQL cluster of our own: `initdb` in a temp dir owned by `postgres`, run with `pg_ctl`."""

    def __init__(self, base: Path, port: int, log: Path) -> None:
        self.bin = postgres_bin()
        self.base = base
        self.data = base / "data"
        self.sockets = base / "sockets"
        self.port = port
        self.log = log

    def _run(self, *argv: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [*_as_postgres(), *argv],
            capture_output=True,
            text=True,
            timeout=timeout,
            start_new_session=True,
            cwd=self.base,
            check=False,
        )

    def init(self) -> None:
        self.base.mkdir(parents=True)
        self.sockets.mkdir()
        self.log.touch()
        if os.geteuid() == 0:
            user = pwd.getpwnam("postgres")
            for path in (self.base, self.sockets, self.log):
                os.chown(path, user.pw_uid, user.pw_gid)
        done = self._run(
            str(self.bin / "initdb"),
            "-D",
            str(self.data),
            "-U",
            "postgres",
            "-A",
            "trust",
            "-E",
            "UTF8",
            "--no-sync",
        )
        if done.returncode != 0:
            raise RuntimeError(f"initdb failed: {done.stdout}{done.stderr}")
        settings = {
            "port": str(self.port),
            "listen_addresses": "'127.0.0.1'",
            "unix_socket_directories": f"'{self.sockets}'",
            # No fsync: the fault is a server crash, never the machine's, so what is written survives in
            # the page cache. Never synchronous_commit = off: a crash (`-m immediate`) would lose commits
            # the server had confirmed, which the product rightly relies on.
            "fsync": "off",
            "max_connections": "200",
            "log_line_prefix": "'%m [%p] '",
        }
        with (self.data / "postgresql.conf").open("a") as conf:
            conf.write("\n# fault suite\n" + "".join(f"{k} = {v}\n" for k, v in settings.items()))

    def start(self) -> None:
        done = self._run(
            str(self.bin / "pg_ctl"), "-D", str(self.data), "-l", str(self.log), "-w", "-t", "60", "start"
        )
        if done.returncode != 0:
            raise RuntimeError(f"pg_ctl start failed: {done.stdout}{done.stderr}; {log_tail(self.log)}")

    def stop_immediate(self) -> None:
        done = self._run(str(self.bin / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop")
        if done.returncode != 0 and self.running():
            raise RuntimeError(f"pg_ctl stop failed: {done.stdout}{done.stderr}")

    def pid(self) -> int | None:
        try:
            return int((self.data / "postmaster.pid").read_text().split("\n", 1)[0])
        except (FileNotFoundError, ValueError, IndexError):
            return None

    def running(self) -> bool:
        pid = self.pid()
        return pid is not None and _alive(pid)

    def _ours(self, pid: int) -> bool:
        """The process is a postmaster of our data directory (not some process that reused the pid)."""
        try:
            return str(self.data) in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
        except FileNotFoundError:
            return False

    def teardown(self) -> None:
        """Stop it whatever happens: pg_ctl, else SIGKILL of the postmaster named in our own data dir."""
        if not self.data.exists():
            return
        with contextlib.suppress(Exception):
            self.stop_immediate()
        pid = self.pid()
        if pid is not None and _alive(pid) and self._ours(pid):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(") ", 1)[1][:1] not in ("Z", "X")


@dataclass
class StackConfig:
    robots: int = 10
    name_prefix: str = "fr"
    speed: float = 3.0  # m/s: a mission of a few short legs takes a few seconds
    keep_logs: Path | None = None


@dataclass
class Stack:
    """The private stack. Use as a context manager: everything is torn down on exit, even on failure."""

    config: StackConfig = field(default_factory=StackConfig)

    def __post_init__(self) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="fleet-faults-"))
        os.chmod(self.tmp, 0o755)  # the postgres user must reach its data directory inside
        self.logs = self.tmp / "logs"
        self.logs.mkdir()
        self.pg_port, self.redis_port, self.mqtt_port, self.api_port = free_ports(4)
        self.postgres = Postgres(self.tmp / "pg", self.pg_port, self.logs / "postgres.log")
        self.processes: dict[str, Proc] = {}
        self.robots: list[RobotConfig] = spread_robots(self.config.robots, self.config.name_prefix)
        # Processes the fault injector is keeping down now: the watcher leaves them alone.
        self.down: set[str] = set()
        self.lock = threading.RLock()
        self.exits: list[ProcessExit] = []
        self._watching = threading.Event()
        self._watcher: threading.Thread | None = None
        self.env = self._env()
        self.api_token = ""  # the load's bearer token, made in the stack's database (_database)
        # where each robot last reported itself (serial -> x, y, theta), for restarts: the run's observer
        self.poses: Callable[[], Mapping[str, tuple[float, float, float]]] = dict

    @property
    def api_url(self) -> str:
        return f"http://127.0.0.1:{self.api_port}"

    @property
    def redis_url(self) -> str:
        return f"redis://127.0.0.1:{self.redis_port}/0"

    def _env(self) -> dict[str, str]:
        inherited = {k: v for k, v in os.environ.items() if not k.startswith(("FLEET_", "DJANGO_"))}
        return {
            **inherited,
            **SERVER_ENV,
            "FLEET_DB_HOST": "127.0.0.1",
            "FLEET_DB_PORT": str(self.pg_port),
            "FLEET_DB_NAME": DB_NAME,
            "FLEET_REDIS_URL": self.redis_url,
            "FLEET_MQTT_HOST": "127.0.0.1",
            "FLEET_MQTT_PORT": str(self.mqtt_port),
            "FLEET_API_PORT": str(self.api_port),
            "DJANGO_SETTINGS_MODULE": "fleet.settings",
            "PYTHONUNBUFFERED": "1",
            "PYTHONPATH": str(ROOT),  # this checkout's code, whatever the venv's editable install points at
        }

    # --- the services -------------------------------------------------------------------------------

    def _add(self, name: str, argv: list[str], *, start: bool = True) -> Proc:
        process = Proc(name, argv, self.env, self.logs / f"{name}.log")
        self.processes[name] = process
        if start:
            process.start()
        return process

    def _services(self) -> None:
        redis_dir = self.tmp / "redis"
        redis_dir.mkdir()
        self._add("redis", redis_server_command(self.redis_port, redis_dir))
        broker = write_broker_config(self.tmp / "mosquitto.conf", self.mqtt_port)
        self._add("broker", ["mosquitto", "-c", str(broker)])
        self.postgres.init()
        self.postgres.start()
        self._wait_serving("redis", self.redis_port)
        self._wait_serving("broker", self.mqtt_port)

    def _wait_serving(self, name: str, port: int) -> None:
        process = self.processes[name]

        def serving() -> bool:
            if not process.running():
                code = process.kill()
                raise RuntimeError(
                    f"{name} exited with code {code} while starting{outside_hint(log_tail(process.log))}: "
                    f"{log_tail(process.log)}"
                )
            return port_open(port)

        wait_until(serving, f"the private {name} on port {port}")

    def _database(self) -> None:
        for argv in (
            [PYTHON, "deploy/ensure_database.py"],
            [PYTHON, "manage.py", "migrate", "--noinput", "-v0"],
        ):
            done = subprocess.run(argv, cwd=ROOT, env=self.env, capture_output=True, text=True, check=False)
            if done.returncode != 0:
                raise RuntimeError(f"{' '.join(argv[1:])} failed: {done.stdout}{done.stderr}")
        self.api_token = api_token_create(self.env, "faults")

    def _ours(self) -> None:
        """The processes of deploy/Procfile on the private services, and the simulator."""
        self._add("api", api_command(self.api_port, access_log=True))
        self._add("bridge", [PYTHON, "manage.py", "mqtt_bridge"])
        self._add("worker", worker_command("steps", "faults-steps", 12))
        self._add("notify", worker_command("notify", "faults-notify", 8))
        self._add("beat", [CELERY, "-A", "fleet", "beat", "--schedule", str(self.tmp / "beat-schedule")])
        self._add("simulator", self._simulator_command(["--count", str(self.config.robots)]))
        wait_until(self.api_ready, "the API's /health", timeout=90, period=0.3)

    def _simulator_command(self, robots: list[str]) -> list[str]:
        """The simulator of our robots (`robots`: `--count N`, or `--robots` specs with start poses)."""
        return [
            PYTHON,
            "-m",
            "simulator",
            *robots,
            "--name-prefix",
            self.config.name_prefix,
            "--mqtt_host",
            "127.0.0.1",
            "--mqtt_port",
            str(self.mqtt_port),
            "--speed",
            str(self.config.speed),
            "--tick_period",
            "0.1",
            "--state_period",
            "1.0",
            "--visualization_period",
            "0",
        ]

    def api_ready(self) -> bool:
        try:
            with urllib.request.urlopen(f"{self.api_url}/health", timeout=2) as response:
                return response.status == 200
        except OSError:
            return False

    def redis_ready(self) -> bool:
        import redis

        try:
            return bool(redis.Redis.from_url(self.redis_url, socket_timeout=1).ping())
        except redis.RedisError:
            return False

    def __enter__(self) -> Stack:
        try:
            self._services()
            self._database()
            self._ours()
            self._watcher = threading.Thread(target=self._watch, name="process-watcher", daemon=True)
            self._watching.set()
            self._watcher.start()
        except BaseException:
            self.teardown()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.teardown()

    # --- faults --------------------------------------------------------------------------------------

    def take_down(self, name: str) -> None:
        """SIGKILL one of our processes (`pg_ctl stop -m immediate` for PostgreSQL) and keep it down."""
        with self.lock:
            self.down.add(name)
            if name == "postgres":
                self.postgres.stop_immediate()
            else:
                self.processes[name].kill()

    def bring_up(self, name: str) -> None:
        """Start it again; the simulator's robots (restarted: no order, headerIds from 0) where `poses`
        last saw them."""
        with self.lock:
            if name == "postgres":
                self.postgres.start()
            else:
                if name == "simulator":
                    self.processes[name].argv = self._simulator_command(["--robots", *self._robot_specs()])
                self.processes[name].start()
            self.down.discard(name)

    def _robot_specs(self) -> list[str]:
        poses = self.poses()
        return [
            "{},{},{},{}".format(robot.name, *poses.get(robot.name, (robot.x, robot.y, robot.theta)))
            for robot in self.robots
        ]

    def running_now(self) -> dict[str, bool]:
        with self.lock:
            return {
                "postgres": self.postgres.running(),
                **{name: process.running() for name, process in self.processes.items()},
            }

    def _watch(self) -> None:
        """Every process that ends without the injector killing it is an unexpected exit: record it (with
        its log's last lines) and start it again, so the run goes on."""
        while self._watching.is_set():
            with self.lock:
                for name, running in self.running_now().items():
                    if running or name in self.down or not self._watching.is_set():
                        continue
                    if name == "postgres":
                        self.exits.append(ProcessExit(name, time.time(), None, log_tail(self.postgres.log)))
                        with contextlib.suppress(Exception):
                            self.postgres.start()
                    else:
                        process = self.processes[name]
                        code = process.kill()  # what is left of its group, then the exit code
                        tail = log_tail(process.log)
                        self.exits.append(ProcessExit(name, time.time(), code, tail + outside_hint(tail)))
                        if sum(1 for e in self.exits if e.name == name) <= MAX_RESTARTS:
                            process.start()
                        else:  # a crash loop: leave it down, reported as not running at the end
                            self.down.add(name)
            time.sleep(0.25)

    # --- teardown ------------------------------------------------------------------------------------

    def stop_watching(self) -> None:
        self._watching.clear()
        if self._watcher is not None:
            self._watcher.join(timeout=10)

    def teardown(self) -> None:
        self.stop_watching()
        ours = [p for name, p in self.processes.items() if name not in ("redis", "broker")]
        for process in ours:
            process.signal_group(signal.SIGTERM)
        for process in ours:
            with contextlib.suppress(Exception):
                process.stop(timeout=10)
        for name in ("redis", "broker"):
            if name in self.processes:
                with contextlib.suppress(Exception):
                    self.processes[name].kill()
        self.postgres.teardown()
        if self.config.keep_logs is not None:
            self.config.keep_logs.mkdir(parents=True, exist_ok=True)
            for log in self.logs.iterdir():
                shutil.copy2(log, self.config.keep_logs / log.name)
        shutil.rmtree(self.tmp, ignore_errors=True)


def write_broker_config(path: Path, port: int) -> Path:
    path.write_text(
        f"listener {port} 127.0.0.1\n"
        "allow_anonymous true\n"
        "persistence false\n"
        "set_tcp_nodelay true\n"
        "log_dest stdout\n"
        "log_timestamp_format %Y-%m-%dT%H:%M:%S\n"
    )
    return path


class PrivateBroker:
    """A Mosquitto of our own on a free port (for tests that restart a broker): never the machine's."""

    def __init__(self, directory: Path) -> None:
        self.port = free_port()
        config = write_broker_config(directory / "mosquitto.conf", self.port)
        self.process = Proc(
            "broker", ["mosquitto", "-c", str(config)], dict(os.environ), directory / "broker.log"
        )

    def start(self) -> None:
        self.process.start()
        wait_until(lambda: port_open(self.port), f"the private Mosquitto on port {self.port}", timeout=30)

    def kill(self) -> None:
        self.process.kill()

    def __enter__(self) -> PrivateBroker:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()
