"""The bridge's robot directory: which robot a topic belongs to, and the version the bridge speaks to it."""

import time

from robots.choices import SettingSource
from robots.models import Robot
from vda5050.topics import RobotIdentity, major_version_of
from vda5050.versions import SUPPORTED_VERSIONS
from workers import tuning

SPOKEN_MAJORS = frozenset(major_version_of(version) for version in SUPPORTED_VERSIONS)


class RobotDirectory:
    """Which robot a topic belongs to: (interface, major version, manufacturer, serial number) -> name.

    A robot whose version no operator chose is found on every major version we speak: the version it
    speaks is learned from its messages (`Bridge._learn_version`)."""

    def __init__(self) -> None:
        self._names: dict[RobotIdentity, str] = {}
        self.versions: dict[str, tuple[str, bool]] = {}  # name -> (version we speak, chosen by an operator)
        self._loaded_at = float("-inf")

    def name(self, identity: RobotIdentity) -> str | None:
        name = self._names.get(identity)
        if name is None and time.monotonic() - self._loaded_at > tuning.DIRECTORY_REFRESH_SECONDS:
            self.reload()
            name = self._names.get(identity)
        return name

    def reload(self) -> None:
        rows = Robot.objects.values_list(
            "name",
            "interface_name",
            "manufacturer",
            "serial_number",
            "protocol_version",
            "protocol_version_source",
        )
        self._names = {}
        self.versions = {}
        for name, interface, manufacturer, serial, version, source in rows:
            by_operator = source == SettingSource.OPERATOR
            majors = {major_version_of(version)} if by_operator else SPOKEN_MAJORS
            for major in majors:
                self._names[RobotIdentity(interface, major, manufacturer, serial)] = name
            self.versions[name] = (version, by_operator)
        self._loaded_at = time.monotonic()
