"""``python -m simulator``: options compatible with Isaac Mission Dispatch's simulator, plus fleet sizes."""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import time
from pathlib import Path

from simulator.config import (
    DEFAULT_BATTERY,
    DEFAULT_BATTERY_DRAIN,
    DEFAULT_CHARGE_RATE,
    DEFAULT_INTERFACE_NAME,
    ROBOT_SPEC_FIELDS,
    Credentials,
    RobotConfig,
    SimulationSettings,
    parse_credentials,
    parse_robot_spec,
    spread_robots,
)
from simulator.robot import SimulatedRobot
from simulator.runner import BrokerSettings, Fleet
from vda5050.topics import RobotAddress, major_version_of
from vda5050.versions import SUPPORTED_VERSIONS

logger = logging.getLogger("simulator")

DEFAULT_ROBOT = "carter01,0,0"
PREFIX_LEVELS = 3  # interfaceName/majorVersion/manufacturer


def add_broker_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the broker is and how to log in, for the simulator and `simulator.monitor` alike."""
    parser.add_argument("--mqtt_host", default="localhost")
    parser.add_argument("--mqtt_port", type=int, default=1883)
    parser.add_argument("--mqtt_transport", choices=("tcp", "websockets"), default="tcp")
    parser.add_argument(
        "--mqtt_ws_path", default="/mqtt", help="websocket path (--mqtt_transport websockets)"
    )
    parser.add_argument("--mqtt_username", default=None, help="shared by every robot without credentials")
    parser.add_argument("--mqtt_password", default=None)
    parser.add_argument("--mqtt_tls", action="store_true", help="connect over TLS (wss with websockets)")
    parser.add_argument("--mqtt_ca_file", default=None, help="CA certificate(s) (default: the system's)")
    parser.add_argument(
        "--mqtt_no_check_hostname",
        dest="mqtt_check_hostname",
        action="store_false",
        help="accept a broker certificate issued for another host name",
    )
    parser.add_argument("--mqtt_cert_file", default=None, help="client certificate, if the broker wants one")
    parser.add_argument("--mqtt_key_file", default=None, help="its private key (default: in the cert file)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m simulator", description="Simulated VDA 5050 robots, one MQTT connection each."
    )
    parser.add_argument(
        "--robots",
        nargs="+",
        default=[],
        metavar="SPEC",
        help=f"robots as {ROBOT_SPEC_FIELDS} (default {DEFAULT_ROBOT} unless --count is given)",
    )
    parser.add_argument("--count", type=int, default=0, help="add N robots spread out on a grid")
    parser.add_argument(
        "--name-prefix",
        "--name_prefix",
        dest="name_prefix",
        default="robot",
        help="name (and serial number) prefix of --count robots",
    )
    parser.add_argument("--speed", type=float, default=1.0, help="m/s (and rad/s turning); 0 = --instant")
    parser.add_argument("--tick_period", type=float, default=0.25, help="s between motion steps")
    parser.add_argument("--instant", action="store_true", help="complete every order at once (benchmarks)")
    parser.add_argument(
        "--battery",
        type=float,
        default=DEFAULT_BATTERY,
        help="percent of battery at start, of robots whose spec gives none",
    )
    parser.add_argument(
        "--battery_drain",
        type=float,
        default=DEFAULT_BATTERY_DRAIN,
        help="percent of battery per metre driven, of robots whose spec gives none",
    )
    parser.add_argument(
        "--charge_rate",
        type=float,
        default=DEFAULT_CHARGE_RATE,
        help="percent per second while charging, of robots whose spec gives none; 0: no robot charges",
    )
    parser.add_argument(
        "--fail_as_warning",
        action="store_true",
        help="failure_period raises a WARNING (the order completes) instead of a FATAL error",
    )
    parser.add_argument(
        "--state_period", type=float, default=1.0, help="s, longest gap between state messages"
    )
    parser.add_argument("--visualization_period", type=float, default=1.0, help="s; 0 disables visualization")
    parser.add_argument(
        "--vda_version",
        choices=SUPPORTED_VERSIONS,
        default="2.0.0",
        help="protocol version of robots whose spec gives none",
    )
    parser.add_argument("--interface_name", default=DEFAULT_INTERFACE_NAME, help="first topic level")
    parser.add_argument(
        "--mqtt_prefix",
        default=None,
        help="topic prefix interfaceName/majorVersion/manufacturer, e.g. uagv/v2/RobotCompany;"
        " overrides --interface_name and the robots' manufacturers in topics",
    )
    add_broker_arguments(parser)
    parser.add_argument(
        "--mqtt_credentials",
        type=Path,
        default=None,
        metavar="FILE",
        help="each robot's own login: lines 'serial_number username password' (deploy/mosquitto/add-robot)",
    )
    parser.add_argument("--log_level", choices=("DEBUG", "INFO", "WARNING", "ERROR"), default="INFO")
    return parser


def robot_configs(args: argparse.Namespace) -> list[RobotConfig]:
    specs = args.robots or ([] if args.count else [DEFAULT_ROBOT])
    configs = [parse_robot_spec(spec) for spec in specs]
    configs += spread_robots(args.count, args.name_prefix)
    serials = [config.serial for config in configs]
    duplicates = sorted({serial for serial in serials if serials.count(serial) > 1})
    if duplicates:
        raise ValueError(f"serial numbers must be unique (they are topic levels): {', '.join(duplicates)}")
    return configs


def broker_settings(
    args: argparse.Namespace, fleet: list[tuple[RobotConfig, RobotAddress]]
) -> BrokerSettings:
    """Where and how to connect; with ``--mqtt_credentials`` every robot must have its own login."""
    credentials = parse_credentials(args.mqtt_credentials.read_text()) if args.mqtt_credentials else {}
    if credentials:
        missing = [address.serial_number for _, address in fleet if address.serial_number not in credentials]
        if missing:
            raise ValueError(f"{args.mqtt_credentials} has no credentials for {', '.join(missing)}")
    return shared_broker_settings(args, credentials)


def shared_broker_settings(
    args: argparse.Namespace, credentials: dict[str, Credentials] | None = None
) -> BrokerSettings:
    """The options of `add_broker_arguments` as settings, checked."""
    tls_files = (args.mqtt_ca_file, args.mqtt_cert_file, args.mqtt_key_file)
    if not args.mqtt_tls and (any(tls_files) or not args.mqtt_check_hostname):
        raise ValueError("the --mqtt_*_file options and --mqtt_no_check_hostname need --mqtt_tls")
    return BrokerSettings(
        host=args.mqtt_host,
        port=args.mqtt_port,
        transport=args.mqtt_transport,
        ws_path=args.mqtt_ws_path,
        username=args.mqtt_username,
        password=args.mqtt_password,
        credentials=credentials or {},
        tls=args.mqtt_tls,
        ca_file=args.mqtt_ca_file,
        check_hostname=args.mqtt_check_hostname,
        cert_file=args.mqtt_cert_file,
        key_file=args.mqtt_key_file,
    )


def topic_address(config: RobotConfig, args: argparse.Namespace) -> RobotAddress:
    """Topic levels of one robot: ``--mqtt_prefix`` if given, else interface/v<major>/manufacturer."""
    version = config.vda_version or args.vda_version
    if args.mqtt_prefix is None:
        return RobotAddress(args.interface_name, config.manufacturer, config.serial, version)
    levels = args.mqtt_prefix.strip("/").split("/")
    if len(levels) != PREFIX_LEVELS:
        raise ValueError(
            f"--mqtt_prefix {args.mqtt_prefix!r} must be interfaceName/majorVersion/manufacturer"
        )
    interface_name, major, manufacturer = levels
    if major != major_version_of(version):
        raise ValueError(
            f"--mqtt_prefix major version {major!r} does not match robot {config.name}'s {version}"
        )
    return RobotAddress(interface_name, manufacturer, config.serial, version)


def settings_from(args: argparse.Namespace) -> SimulationSettings:
    if min(args.speed, args.visualization_period, args.battery_drain, args.charge_rate) < 0:
        raise ValueError("--speed, --visualization_period, --battery_drain, --charge_rate must be >= 0")
    if args.tick_period <= 0 or args.state_period <= 0:
        raise ValueError("--tick_period, --state_period must be > 0")
    if not 0 <= args.battery <= 100:
        raise ValueError("--battery must be a percentage")
    return SimulationSettings(
        speed=args.speed,
        tick_period=args.tick_period,
        state_period=args.state_period,
        visualization_period=args.visualization_period,
        fail_as_warning=args.fail_as_warning,
        version=args.vda_version,
        instant=args.instant,
        battery=args.battery,
        battery_drain=args.battery_drain,
        charge_rate=args.charge_rate,
    )


async def simulate(
    fleet: list[tuple[RobotConfig, RobotAddress]], settings: SimulationSettings, broker: BrokerSettings
) -> None:
    """Run until SIGINT/SIGTERM, then publish OFFLINE for every robot and disconnect."""
    now = time.time()
    robots = [SimulatedRobot(config, settings, now=now, topic_address=address) for config, address in fleet]
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    logger.info("simulating %d robots against %s:%s", len(robots), broker.host, broker.port)
    await Fleet(robots, broker, settings.tick_period).run(stop)


def main(argv: list[str] | None = None) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        settings = settings_from(args)
        fleet = [(config, topic_address(config, args)) for config in robot_configs(args)]
        broker = broker_settings(args, fleet)
    except (ValueError, OSError) as exc:  # ProtocolError (a bad id or version) is a ValueError too
        parser.error(str(exc))
    asyncio.run(simulate(fleet, settings, broker))
