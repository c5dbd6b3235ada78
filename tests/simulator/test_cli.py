"""Robot specs and command-line options."""

from __future__ import annotations

import pytest

from simulator.cli import build_parser, robot_configs, settings_from, topic_address
from simulator.config import RobotConfig, RobotType, parse_robot_spec


def test_short_spec_uses_the_reference_defaults() -> None:
    config = parse_robot_spec("carter01,4,5")
    assert config == RobotConfig(name="carter01", x=4.0, y=5.0)
    assert (config.theta, config.map_id, config.failure_period, config.battery) == (0.0, "map", 0, 20.0)
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
