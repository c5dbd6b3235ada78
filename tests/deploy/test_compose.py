"""deploy/compose.yaml, statically: every Procfile process is a service, the workers scale, beat does not,
the broker runs the shipped production configuration, and every file it mounts exists or is made by
make-secrets."""

import re
from pathlib import Path
from typing import Any

import yaml

from tests.deploy.layout import DEPLOY, procfile_processes

COMPOSE: dict[str, Any] = yaml.safe_load((DEPLOY / "compose.yaml").read_text())
SERVICES: dict[str, Any] = COMPOSE["services"]
SECRETS_DEFAULT = "${FLEET_COMPOSE_SECRETS:-./compose/secrets}"


def mount(volume: str) -> tuple[str, str]:
    """(source, target) of a `source:target:ro` volume; the source may hold `${VAR:-default}`."""
    source, target = volume.removesuffix(":ro").removesuffix(":rw").rsplit(":", 1)
    return source, target


def test_every_procfile_process_is_a_service_running_its_role():
    for process in procfile_processes():
        command = SERVICES[process]["command"]
        role = command[0] if isinstance(command, list) else command.split()[0]
        assert role == process
        assert SERVICES[process]["image"] == "${FLEET_IMAGE:-localhost/mission-dispatch:latest}"


def test_every_service_of_our_image_runs_a_procfile_process_or_migrate():
    ours = {name for name, service in SERVICES.items() if service["image"].startswith("${FLEET_IMAGE")}
    assert ours == {*procfile_processes(), "migrate"}


def test_migrate_runs_once_before_the_servers():
    assert SERVICES["migrate"]["command"] == ["migrate"]
    assert SERVICES["migrate"]["restart"] == "on-failure"
    assert SERVICES["migrate"]["depends_on"] == {"postgres": {"condition": "service_healthy"}}
    for server in ("api", "bridge", "worker", "notify", "beat"):
        assert SERVICES[server]["depends_on"]["migrate"] == {"condition": "service_completed_successfully"}


def test_workers_scale_and_beat_is_one():
    for name in ("worker", "beat"):
        assert "container_name" not in SERVICES[name]
        assert "ports" not in SERVICES[name]
    assert SERVICES["worker"]["deploy"] == {"replicas": "${FLEET_COMPOSE_WORKERS:-1}"}
    assert "deploy" not in SERVICES["beat"]
    assert "scale" not in SERVICES["beat"]


def test_servers_have_health_checks_of_their_role():
    for role in ("api", "bridge", "worker", "notify", "beat"):
        assert SERVICES[role]["healthcheck"]["test"] == f"/app/deploy/container/entrypoint health {role}"


def test_the_servers_are_configured_by_fleet_variables_and_secret_files_only():
    environment = SERVICES["api"]["environment"]
    assert all(name.startswith("FLEET_") for name in environment)
    assert environment["FLEET_SECRET_KEY_FILE"] == "/run/secrets/secret-key"
    assert environment["FLEET_DB_PASSWORD_FILE"] == "/run/secrets/db-password"
    assert environment["FLEET_MQTT_PASSWORD_FILE"] == "/run/secrets/mqtt-password"
    assert environment["FLEET_MQTT_TLS"] == "${MQTT_TLS:-on}"
    assert set(SERVICES["api"]["secrets"]) == {"secret-key", "db-password", "mqtt-password", "mqtt-ca"}


def test_the_broker_is_the_shipped_production_configuration():
    mqtt = SERVICES["mqtt"]
    mounts = {target: source for source, target in map(mount, mqtt["volumes"])}
    assert mounts["/etc/mosquitto/mosquitto.conf"] == "./mosquitto/mosquitto.conf"
    assert mounts["/etc/mosquitto/acl"] == "./mosquitto/acl"
    assert mqtt["command"] == ["mosquitto", "-c", "/etc/mosquitto/mosquitto.conf"]
    conf = (DEPLOY / "mosquitto" / "mosquitto.conf").read_text()
    for path in re.findall(r"^(?:password_file|acl_file|certfile|keyfile|cafile) (\S+)", conf, re.MULTILINE):
        assert path in mounts or str(Path(path).parent) in mounts, path
    assert "allow_anonymous false" in conf


def test_the_plain_profile_and_the_simulator_profile():
    assert SERVICES["mqtt-plain"]["profiles"] == ["plain"]
    assert SERVICES["simulator"]["profiles"] == ["simulator"]
    plain_env = dict(
        line.split("=", 1)
        for line in (DEPLOY / "compose" / "plain.env").read_text().splitlines()
        if line and not line.startswith("#")
    )
    assert plain_env["MQTT_HOST"] == "mqtt-plain"
    assert plain_env["MQTT_TLS"] == "off"
    assert "listener 1883" in (DEPLOY / "compose" / "mosquitto-plain.conf").read_text()


def test_mounted_files_exist_or_are_made_by_make_secrets():
    make_secrets = (DEPLOY / "compose" / "make-secrets").read_text()
    sources = [secret["file"] for secret in COMPOSE["secrets"].values()]
    sources += [mount(volume)[0] for service in SERVICES.values() for volume in service.get("volumes", [])]
    for source in sources:
        if source.startswith(SECRETS_DEFAULT):
            made = source.removeprefix(SECRETS_DEFAULT + "/")
            assert made.split("/")[-1] in make_secrets, made
        elif source.startswith("./"):
            assert (DEPLOY / source).exists(), source
        else:
            assert source in COMPOSE["volumes"], source
