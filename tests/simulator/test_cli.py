"""Robot specs and command-line options."""

from __future__ import annotations

import argparse
import ssl
from pathlib import Path

import pytest

from simulator.cli import broker_settings, build_parser, robot_configs, settings_from, topic_address
from simulator.config import (
    Credentials,
    RobotConfig,
    RobotType,
    SimulationSettings,
    parse_credentials,
    parse_robot_spec,
)
from vda5050.topics import RobotAddress


def test_short_spec_uses_the_reference_defaults() -> None:
    config = parse_robot_spec("carter01,4,5")
    assert config == RobotConfig(name="carter01", x=4.0, y=5.0)
    assert (config.theta, config.map_id, config.failure_period) == (0.0, "map", 0)
    assert config.battery_at_start(SimulationSettings()) == 20.0
    assert (config.manufacturer, config.serial, config.robot_type) == ("RobotCompany", "carter01", "CARRIER")


def test_full_spec() -> None:
    config = parse_robot_spec("arm,1,2,3.14,floor2,3,55.5,Acme,sn-9,manipulator")
    assert config == RobotConfig(
        "arm", 1.0, 2.0, 3.14, "floor2", 3, 55.5, "Acme", "sn-9", RobotType.MANIPULATOR
    )
    assert config.serial == "sn-9"


@pytest.mark.parametrize(
    "spec",
    ["carter01", "carter01,1", "c,x,1", "c,1,2,0,map,-1", "c,1,2,0,map,0,101", "c,1,2,0,map,0,5,A,s,ROBOT"],
)
def test_bad_specs_are_refused(spec: str) -> None:
    with pytest.raises(ValueError):
        parse_robot_spec(spec)


def test_count_adds_robots_spread_out_with_unique_names() -> None:
    args = build_parser().parse_args(["--robots", "carter01,0,0", "--count", "12", "--name-prefix", "bench"])
    configs = robot_configs(args)
    assert [c.name for c in configs[:3]] == ["carter01", "bench01", "bench02"]
    assert len(configs) == 13
    assert len({(c.x, c.y) for c in configs[1:]}) == 12


def test_duplicate_serial_numbers_are_refused() -> None:
    args = build_parser().parse_args(["--robots", "a,0,0", "b,1,1,0,map,0,20,RobotCompany,a"])
    with pytest.raises(ValueError, match="unique"):
        robot_configs(args)


def test_topics_default_to_interface_version_manufacturer_serial() -> None:
    args = build_parser().parse_args(["--interface_name", "fleet7", "--vda_version", "2.1.0"])
    (config,) = robot_configs(args)
    address = topic_address(config, args)
    assert (address.interface_name, address.major_version, address.manufacturer, address.serial_number) == (
        "fleet7",
        "v2",
        "RobotCompany",
        "carter01",
    )


def test_mqtt_prefix_overrides_interface_and_manufacturer_levels() -> None:
    args = build_parser().parse_args(["--robots", "r1,0,0,0,map,0,20,Acme", "--mqtt_prefix", "ifc/v2/Shared"])
    (config,) = robot_configs(args)
    address = topic_address(config, args)
    assert (address.interface_name, address.manufacturer) == ("ifc", "Shared")
    with pytest.raises(ValueError):
        topic_address(config, build_parser().parse_args(["--mqtt_prefix", "ifc/v3/Shared"]))
    with pytest.raises(ValueError):
        topic_address(config, build_parser().parse_args(["--mqtt_prefix", "too/short"]))


def test_speed_zero_or_instant_completes_orders_at_once() -> None:
    parse = build_parser().parse_args
    assert settings_from(parse(["--speed", "0"])).completes_instantly
    assert settings_from(parse(["--instant"])).completes_instantly
    assert not settings_from(parse([])).completes_instantly
    with pytest.raises(ValueError):
        settings_from(parse(["--tick_period", "0"]))


def fleet_of(args: argparse.Namespace) -> list[tuple[RobotConfig, RobotAddress]]:
    return [(config, topic_address(config, args)) for config in robot_configs(args)]


def test_each_robot_logs_in_with_its_own_credentials(tmp_path: Path) -> None:
    credentials = tmp_path / "credentials"
    credentials.write_text("# serial username password\na a secret-a\n\nb user-b secret-b\n")
    argv = ["--robots", "a,0,0", "b,1,1", "--mqtt_credentials", str(credentials), "--mqtt_username", "shared"]
    args = build_parser().parse_args(argv)
    broker = broker_settings(args, fleet_of(args))
    assert broker.login("a") == Credentials("a", "secret-a")
    assert broker.login("b") == Credentials("user-b", "secret-b")
    assert broker.login("c") == Credentials("shared", None)  # not in the file: the shared login


def test_a_robot_missing_from_the_credentials_file_is_refused(tmp_path: Path) -> None:
    credentials = tmp_path / "credentials"
    credentials.write_text("a a secret-a\n")
    args = build_parser().parse_args(["--robots", "a,0,0", "b,1,1", "--mqtt_credentials", str(credentials)])
    with pytest.raises(ValueError, match="no credentials for b"):
        broker_settings(args, fleet_of(args))


@pytest.mark.parametrize("text", ["a a\n", "a a secret extra\n", "a a s1\na a s2\n"])
def test_bad_credentials_lines_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="line"):
        parse_credentials(text)


def test_tls_options() -> None:
    args = build_parser().parse_args(["--mqtt_tls", "--mqtt_no_check_hostname"])
    broker = broker_settings(args, fleet_of(args))
    context = broker.tls_context()
    assert context is not None and not context.check_hostname
    assert context.verify_mode == ssl.CERT_REQUIRED  # the broker's certificate is still checked
    assert broker_settings(build_parser().parse_args([]), []).tls_context() is None


@pytest.mark.parametrize("option", [["--mqtt_ca_file", "ca.crt"], ["--mqtt_no_check_hostname"]])
def test_tls_options_need_tls(option: list[str]) -> None:
    args = build_parser().parse_args(option)
    with pytest.raises(ValueError, match="need --mqtt_tls"):
        broker_settings(args, fleet_of(args))
