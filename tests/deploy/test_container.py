"""The deployment run for real: the image built from the locally made Debian base, `compose up` with the
simulator profile (the production broker: TLS, logins, ACL), the README's curl examples against it, and the
missions they post run to their ends. Marked `container`; it skips, saying why, where no container engine
(Debian's podman with runc, podman-compose) works. Minutes long: images are cached by the engine after the
first run."""

import json
import os
import re
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests

from tests.deploy.layout import DEPLOY, ROOT
from tests.private_redis import free_port
from tests.waiting import wait_for

pytestmark = pytest.mark.container

BASE_IMAGE = "localhost/mission-dispatch-base:bookworm"
IMAGE = "localhost/mission-dispatch:test"
SERVICE_IMAGES = {
    target: f"localhost/mission-dispatch-test-{target}:latest"
    for target in ("postgres", "redis", "mosquitto")
}
PROJECT = "mission-dispatch-test"
CA_BUNDLE = Path("/etc/ssl/certs/ca-certificates.crt")
# What this machine's podman needs (crun fails on its cgroups; setrlimit is refused without explicit limits):
# the test's own settings, never the product's.
CONTAINERS_CONF = """\
[containers]
default_ulimits = ["nofile=1024:1024", "nproc=1024:1024"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
"""
BUILD_SECONDS = 900
MISSION_SECONDS = 240


def run(argv: list[str], env: dict[str, str], timeout: float = BUILD_SECONDS, **kwargs) -> str:
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=timeout, **kwargs)
    assert done.returncode == 0, f"{' '.join(argv)} failed:\n{done.stdout[-5000:]}\n{done.stderr[-5000:]}"
    return done.stdout


def engine_environment(tmp: Path) -> dict[str, str]:
    """The environment for podman: its containers.conf, or a skip saying why no engine works here."""
    for command in ("podman", "podman-compose", "runc"):
        if shutil.which(command) is None:
            pytest.skip(f"{command} not found: apt-get install podman runc podman-compose")
    conf = tmp / "containers.conf"
    conf.write_text(CONTAINERS_CONF)
    env = {**os.environ, "CONTAINERS_CONF": str(conf)}
    probe = subprocess.run(["podman", "info"], env=env, capture_output=True, text=True, timeout=120)
    if probe.returncode != 0:
        pytest.skip(f"podman does not work here: {probe.stderr.strip()[-500:]}")
    return env


def build_images(env: dict[str, str]) -> None:
    """The base (debootstrap, once per machine), the image, and stand-ins for the services' images."""
    have_base = subprocess.run(["podman", "image", "exists", BASE_IMAGE], env=env, timeout=60).returncode == 0
    if not have_base:
        if shutil.which("debootstrap") is None:
            pytest.skip(f"no {BASE_IMAGE} and no debootstrap to make it: apt-get install debootstrap")
        run([str(DEPLOY / "container" / "base-image"), BASE_IMAGE], env)
    secret = ["--secret", f"id=ca,src={CA_BUNDLE}"] if CA_BUNDLE.exists() else []
    build = ["podman", "build", "--network", "host", "--build-arg", f"BASE={BASE_IMAGE}"]
    run([*build, *secret, "-f", str(DEPLOY / "container" / "Dockerfile"), "-t", IMAGE, str(ROOT)], env)
    for target, tag in SERVICE_IMAGES.items():
        services = DEPLOY / "container" / "services.Dockerfile"
        run([*build, "-f", str(services), "--target", target, "-t", tag, str(DEPLOY / "container")], env)


@pytest.fixture(scope="module")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, str]]]:
    """deploy/compose.yaml up with every profile (podman-compose 1.0 starts them all), on free host ports;
    yields the API's base URL and the environment the compose commands need."""
    tmp = tmp_path_factory.mktemp("container")
    env = engine_environment(tmp)
    build_images(env)
    secrets = tmp / "secrets"
    run([str(DEPLOY / "compose" / "make-secrets"), str(secrets)], env, timeout=60)
    api_port = free_port()
    env.update(
        FLEET_IMAGE=IMAGE,
        FLEET_POSTGRES_IMAGE=SERVICE_IMAGES["postgres"],
        FLEET_REDIS_IMAGE=SERVICE_IMAGES["redis"],
        FLEET_MOSQUITTO_IMAGE=SERVICE_IMAGES["mosquitto"],
        FLEET_COMPOSE_SECRETS=str(secrets),
        API_PUBLISHED_PORT=str(api_port),
        MQTT_TLS_PUBLISHED_PORT=str(free_port()),
        MQTT_PLAIN_PUBLISHED_PORT=str(free_port()),
        FLEET_COMPOSE_WORKERS="2",
    )
    compose = ["podman-compose", "-p", PROJECT, "-f", str(DEPLOY / "compose.yaml")]
    down(compose, env)
    try:
        run(
            [*compose, "--profile", "simulator", "up", "-d"]
            if compose_has_profiles(env)
            else [*compose, "up", "-d"],
            env,
        )
        url = f"http://127.0.0.1:{api_port}"
        wait_for(lambda: api_answers(url), "the API's GET /health", timeout=120)
        yield url, env
    finally:
        down(compose, env)


def compose_has_profiles(env: dict[str, str]) -> bool:
    done = subprocess.run(["podman-compose", "--help"], env=env, capture_output=True, text=True, timeout=60)
    return "--profile" in done.stdout


def down(compose: list[str], env: dict[str, str]) -> None:
    """The test project's containers, volumes and network gone (podman-compose 1.0 keeps the network)."""
    subprocess.run([*compose, "down", "-v"], env=env, capture_output=True, timeout=300)
    subprocess.run(
        ["podman", "network", "rm", "-f", f"{PROJECT}_default"], env=env, capture_output=True, timeout=60
    )


def api_answers(url: str) -> bool:
    try:
        return requests.get(f"{url}/health", timeout=5).status_code == 200
    except requests.ConnectionError:
        return False


def readme_blocks() -> list[str]:
    """The shell blocks of README.md's "Try it" section, in order."""
    section = (ROOT / "README.md").read_text().split("## Try it", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)```", section, flags=re.DOTALL)


def run_readme_block(block: str, url: str, token: str, env: dict[str, str]) -> str:
    """`block` as a user runs it after `export TOKEN=...`, against the stack's API port."""
    script = block.replace("$(cat .fleet/dev-token)", token).replace(
        "localhost:5000", url.removeprefix("http://")
    )
    return run(["bash", "-euo", "pipefail", "-c", script], {**env, "TOKEN": token}, timeout=120)


def missions(url: str, token: str) -> dict[str, dict]:
    response = requests.get(f"{url}/mission", headers={"Authorization": f"Bearer {token}"}, timeout=10)
    response.raise_for_status()
    return {mission["name"]: mission for mission in response.json()}


def test_the_readme_missions_run_to_their_ends(stack: tuple[str, dict[str, str]]):
    url, env = stack
    # The README's token is the one `make run` keeps; here the deployment's own, as deploy/README.md says.
    output = run(
        [
            "podman",
            "exec",
            f"{PROJECT}_api_1",
            "/app/deploy/container/entrypoint",
            "manage.py",
            "api_token",
            "create",
            "readme",
        ],
        env,
        timeout=120,
    )
    token = output.strip().splitlines()[-1]
    robots, posts, teleop = readme_blocks()[:3]
    run_readme_block(robots, url, token, env)
    run_readme_block(posts, url, token, env)

    def first_two_ended_and_teleop_waits() -> dict[str, dict] | None:
        status = {name: mission["status"] for name, mission in missions(url, token).items()}
        teleop = status["mission_with_teleop"]
        waiting = (
            teleop["state"] == "RUNNING" and teleop["node_status"]["forklift_teleop"]["state"] == "RUNNING"
        )
        ended = status["simple_mission_example"]["state"], status["complex_mission_example"]["state"]
        return status if waiting and ended == ("COMPLETED", "FAILED") else None

    status = wait_for(
        first_two_ended_and_teleop_waits, "the README's first two missions", timeout=MISSION_SECONDS
    )
    assert status["complex_mission_example"]["node_status"]["dropoff_book_at_goal"]["state"] == "FAILED"
    run_readme_block(teleop.splitlines()[0], url, token, env)  # the README's "end teleop" line
    wait_for(
        lambda: missions(url, token)["mission_with_teleop"]["status"]["state"] == "COMPLETED",
        "mission_with_teleop to complete after teleop ended",
        timeout=MISSION_SECONDS,
    )


@pytest.mark.parametrize("role", ["api", "bridge"])
def test_the_servers_log_json_lines(stack: tuple[str, dict[str, str]], role: str):
    _, env = stack
    logs = run(["podman", "logs", f"{PROJECT}_{role}_1"], env, timeout=60)
    lines = [line for line in logs.splitlines() if line.strip()]
    assert lines
    for line in lines:
        assert set(json.loads(line)) >= {"time", "level", "logger", "message"}, line


@pytest.mark.parametrize(
    ("container", "role"),
    [
        ("api_1", "api"),
        ("bridge_1", "bridge"),
        ("worker_1", "worker"),
        ("worker_2", "worker"),
        ("notify_1", "notify"),
        ("beat_1", "beat"),
    ],
)
def test_every_server_passes_its_health_check(stack: tuple[str, dict[str, str]], container: str, role: str):
    """Each of them, the two step workers (FLEET_COMPOSE_WORKERS=2) answering their own pings."""
    _, env = stack
    command = ["podman", "exec", f"{PROJECT}_{container}", "/app/deploy/container/entrypoint", "health", role]
    wait_for(
        lambda: subprocess.run(command, env=env, capture_output=True, timeout=60).returncode == 0,
        f"{role}'s health check",
        timeout=120,
    )


def test_a_health_check_fails_where_its_process_is_not(stack: tuple[str, dict[str, str]]):
    _, env = stack
    command = ["podman", "exec", f"{PROJECT}_worker_1", "/app/deploy/container/entrypoint", "health", "api"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "api unhealthy" in done.stderr
