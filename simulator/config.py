"""What one simulated robot is and how the whole simulation behaves (parsed from the command line)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from vda5050.versions import SUPPORTED_VERSIONS

DEFAULT_MAP_ID = "map"
DEFAULT_BATTERY = 20.0
# Percent per metre driven: none by default. Robots drive to a charger by themselves only where one exists
# (README, "Stations: charging and parking"), so without one a battery that drained would leave a simulated
# fleet below its critical level, taking no missions; `make run` (deploy/Procfile) starts its robots at 80 %
# draining 0.1 % per metre, some 500 m of missions before a minimum of 30 %.
DEFAULT_BATTERY_DRAIN = 0.0
# Percent per second while charging: 20 % to 100 % in 40 s.
DEFAULT_CHARGE_RATE = 2.0
DEFAULT_MANUFACTURER = "RobotCompany"
DEFAULT_INTERFACE_NAME = "uagv"
ROBOT_SPEC_FIELDS = (
    "name,x,y[,theta[,map_id[,failure_period[,battery[,manufacturer[,serial_number[,robot_type"
    "[,vda_version[,stack[,battery_drain[,charge_rate]]]]]]]]]]]]"
)


class RobotType(StrEnum):
    """``robot_type`` of a robot spec; becomes the factsheet's ``agvClass``.

    MANIPULATOR and HUMANOID are Isaac Mission Dispatch's extensions of the VDA 5050 enum.
    """

    FORKLIFT = "FORKLIFT"
    CONVEYOR = "CONVEYOR"
    TUGGER = "TUGGER"
    CARRIER = "CARRIER"
    MANIPULATOR = "MANIPULATOR"
    HUMANOID = "HUMANOID"


class Stack(StrEnum):
    """The vehicle software a robot behaves like: strict (the document, to the letter), or a real stack
    with its known deviations, to test the server's compatibility rules against."""

    STRICT = "strict"
    # npm vda-5050-lib 1.4.0's AgvController (recorded from it): reads instant actions only under the 1.1
    # key `instantActions` and rejects `actions` with a validationError naming it; answers a cancelOrder
    # without an order with a noOrderToCancel error and no action state.
    VDA_5050_LIB_1_4 = "vda-5050-lib-1.4"
    # PyPI vda5050-sdk 0.2.0's vehicle (its VehicleClient and reference OrderExecutor): takes an order update
    # that extends its order (reports the new orderUpdateId and node states), then stands still at the end
    # of the base it had, reporting no error and not driving (its executor fails internally on the update).
    VDA5050_SDK_0_2 = "vda5050-sdk-0.2"


@dataclass(frozen=True)
class RobotConfig:
    """One ``--robots`` entry: who the robot is and where it starts."""

    name: str
    x: float
    y: float
    theta: float = 0.0
    map_id: str = DEFAULT_MAP_ID
    failure_period: int = 0
    battery: float | None = None  # percent at start; None: the simulation's
    manufacturer: str = DEFAULT_MANUFACTURER
    serial_number: str = ""
    robot_type: RobotType = RobotType.CARRIER
    vda_version: str = ""  # empty: the simulation's --vda_version
    stack: Stack = Stack.STRICT
    battery_drain: float | None = None  # percent per metre driven; None: the simulation's
    charge_rate: float | None = None  # percent per second charging; 0: cannot charge; None: the simulation's

    def battery_at_start(self, settings: SimulationSettings) -> float:
        """Its battery's charge at start (percent)."""
        return settings.battery if self.battery is None else self.battery

    def battery_rates(self, settings: SimulationSettings) -> tuple[float, float]:
        """Its battery drain (percent per metre) and charge rate (percent per second; 0: cannot charge)."""
        drain = settings.battery_drain if self.battery_drain is None else self.battery_drain
        return drain, settings.charge_rate if self.charge_rate is None else self.charge_rate

    @property
    def serial(self) -> str:
        """The serial number, which is also the robot's topic level; defaults to the name."""
        return self.serial_number or self.name


@dataclass(frozen=True)
class SimulationSettings:
    """Behaviour shared by every robot of one simulator process."""

    speed: float = 1.0  # m/s, and rad/s when turning on the spot
    tick_period: float = 0.25  # s between motion steps
    state_period: float = 1.0  # s, the longest gap between two state messages
    visualization_period: float = 1.0  # s; 0 disables visualization
    fail_as_warning: bool = False
    version: str = "2.0.0"
    instant: bool = False  # every order completes at once; implied by speed 0
    battery: float = DEFAULT_BATTERY  # percent at start, of robots whose spec gives none
    battery_drain: float = DEFAULT_BATTERY_DRAIN  # of robots whose spec gives none
    charge_rate: float = DEFAULT_CHARGE_RATE  # of robots whose spec gives none

    @property
    def completes_instantly(self) -> bool:
        return self.instant or self.speed == 0

    @property
    def step(self) -> float:
        """How far a robot moves (m) or turns (rad) in one tick."""
        return self.speed * self.tick_period


@dataclass(frozen=True)
class Credentials:
    """An MQTT login: a robot's own (deploy/README.md: the username is its serial number), or the shared
    one, whose password may be left out."""

    username: str
    password: str | None


def parse_credentials(text: str) -> dict[str, Credentials]:
    """``--mqtt_credentials`` file: one ``serial_number username password`` per line; lines starting with
    ``#`` are comments."""
    credentials: dict[str, Credentials] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) != 3:
            raise ValueError(f"credentials line {number} must be 'serial_number username password'")
        serial_number, username, password = fields
        if serial_number in credentials:
            raise ValueError(f"credentials line {number}: {serial_number!r} is listed twice")
        credentials[serial_number] = Credentials(username, password)
    return credentials


def parse_robot_spec(spec: str) -> RobotConfig:
    """``carter01,4,5`` or ``carter02,9,9,3.14,map,3,80,Acme,sn-2,MANIPULATOR,3.0.0`` -> RobotConfig."""
    fields = [field.strip() for field in spec.split(",")]
    if len(fields) < 3 or len(fields) > 14:
        raise ValueError(f"robot spec {spec!r} must be {ROBOT_SPEC_FIELDS}")
    name, x, y, *optional = fields
    if not name:
        raise ValueError(f"robot spec {spec!r} has no name")
    optional += [""] * (11 - len(optional))
    (
        theta,
        map_id,
        failure_period,
        battery,
        manufacturer,
        serial_number,
        robot_type,
        vda_version,
        stack,
        battery_drain,
        charge_rate,
    ) = optional
    config = RobotConfig(
        name=name,
        x=_finite(x, "x", spec),
        y=_finite(y, "y", spec),
        theta=_finite(theta, "theta", spec) if theta else 0.0,
        map_id=map_id or DEFAULT_MAP_ID,
        failure_period=int(failure_period) if failure_period else 0,
        battery=_finite(battery, "battery", spec) if battery else None,
        manufacturer=manufacturer or DEFAULT_MANUFACTURER,
        serial_number=serial_number,
        robot_type=RobotType(robot_type.upper()) if robot_type else RobotType.CARRIER,
        vda_version=vda_version,
        stack=Stack(stack) if stack else Stack.STRICT,
        battery_drain=_finite(battery_drain, "battery_drain", spec) if battery_drain else None,
        charge_rate=_finite(charge_rate, "charge_rate", spec) if charge_rate else None,
    )
    if vda_version and vda_version not in SUPPORTED_VERSIONS:
        raise ValueError(f"robot spec {spec!r}: vda_version must be one of {', '.join(SUPPORTED_VERSIONS)}")
    if config.failure_period < 0:
        raise ValueError(f"robot spec {spec!r}: failure_period must be >= 0")
    if config.battery is not None and not 0 <= config.battery <= 100:
        raise ValueError(f"robot spec {spec!r}: battery must be a percentage")
    if any(rate is not None and rate < 0 for rate in (config.battery_drain, config.charge_rate)):
        raise ValueError(f"robot spec {spec!r}: battery_drain and charge_rate must be >= 0")
    return config


def spread_robots(count: int, name_prefix: str, spacing: float = 2.0) -> list[RobotConfig]:
    """``--count N``: robots ``<prefix>0001``... on a square grid, ``spacing`` metres apart."""
    columns = max(1, math.ceil(math.sqrt(count)))
    width = len(str(count))
    return [
        RobotConfig(
            name=f"{name_prefix}{index + 1:0{width}d}",
            x=(index % columns) * spacing,
            y=(index // columns) * spacing,
        )
        for index in range(count)
    ]


def _finite(text: str, field: str, spec: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"robot spec {spec!r}: {field} must be a finite number")
    return value
