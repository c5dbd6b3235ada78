"""The robot's battery: drained by driving, charged between VDA 5050's `startCharging` and `stopCharging`.

A charge in percent, falling by a rate per metre driven (nothing while standing) and rising by a rate per
second while charging, until full. Charging stops when the robot drives off or the battery is full.
"""

from __future__ import annotations

from dataclasses import dataclass

FULL = 100.0


@dataclass(eq=False)
class Battery:
    charge: float  # percent
    drain_per_metre: float  # percent per metre driven
    charge_rate: float  # percent per second while charging; 0: the robot cannot charge
    charging: bool = False
    charged_until: float = 0.0  # UNIX seconds the charge was last raised to

    @property
    def can_charge(self) -> bool:
        return self.charge_rate > 0

    def drive(self, metres: float) -> None:
        """Driven `metres`: the charge falls."""
        self.charge = max(0.0, self.charge - metres * self.drain_per_metre)

    def start_charging(self, now: float) -> None:
        self.charging = self.charge < FULL
        self.charged_until = now

    def stop_charging(self, now: float) -> None:
        self.charge_until(now)
        self.charging = False

    def charge_until(self, now: float) -> bool:
        """Raise the charge to what `now` brings; True if charging ended (full), which the state reports."""
        if not self.charging:
            return False
        self.charge = min(FULL, self.charge + (now - self.charged_until) * self.charge_rate)
        self.charged_until = now
        if self.charge >= FULL:
            self.charging = False
            return True
        return False
