"""How a simulated robot moves: L-shaped, along X, then along Y, then turning on the spot, as Isaac's
reference simulator does; and its ``Drive``, what it reports of its motion."""

from __future__ import annotations

import math
from dataclasses import dataclass

from simulator.config import SimulationSettings
from simulator.outbox import Outbox
from vda5050.models import Edge, Node, Velocity

DEFAULT_DEVIATION_XY = 0.05  # m, used when a node's allowedDeviationXY is missing or 0
DEFAULT_DEVIATION_THETA = 0.01  # rad, used when a node's allowedDeviationTheta is missing or 0


@dataclass(frozen=True)
class VehiclePose:
    """Where the simulated robot stands on its map and which way it faces."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class Target:
    """Where a node wants the robot; ``theta`` None means any heading will do.

    A missing, zero (the document's "manufacturer default") or negative deviation means the default.
    """

    x: float
    y: float
    theta: float | None
    deviation_xy: float
    deviation_theta: float

    @classmethod
    def of(
        cls,
        x: float,
        y: float,
        theta: float | None,
        deviation_xy: float | None,
        deviation_theta: float | None,
    ) -> Target:
        return cls(
            x=x,
            y=y,
            theta=theta,
            deviation_xy=deviation_xy if deviation_xy and deviation_xy > 0 else DEFAULT_DEVIATION_XY,
            deviation_theta=(
                deviation_theta if deviation_theta and deviation_theta > 0 else DEFAULT_DEVIATION_THETA
            ),
        )

    def within_xy(self, pose: VehiclePose) -> bool:
        return math.hypot(self.x - pose.x, self.y - pose.y) <= self.deviation_xy

    def reached_by(self, pose: VehiclePose) -> bool:
        if not self.within_xy(pose):
            return False
        return self.theta is None or abs(angle_difference(self.theta, pose.theta)) <= self.deviation_theta


def angle_difference(to: float, frm: float) -> float:
    """Signed shortest turn from ``frm`` to ``to``, in [-pi, pi]."""
    return math.atan2(math.sin(to - frm), math.cos(to - frm))


def normalize_angle(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def step_towards(pose: VehiclePose, target: Target, step: float) -> VehiclePose:
    """One tick of motion: at most ``step`` metres along X (then Y), or ``step`` radians of turning."""
    if not target.within_xy(pose):
        dx = target.x - pose.x
        if dx != 0:
            return VehiclePose(pose.x + math.copysign(min(abs(dx), step), dx), pose.y, pose.theta)
        dy = target.y - pose.y
        return VehiclePose(pose.x, pose.y + math.copysign(min(abs(dy), step), dy), pose.theta)
    if target.theta is None:
        return pose
    turn = angle_difference(target.theta, pose.theta)
    return VehiclePose(
        pose.x, pose.y, normalize_angle(pose.theta + math.copysign(min(abs(turn), step), turn))
    )


def jump_to(pose: VehiclePose, target: Target) -> VehiclePose:
    """Instant mode: be at the node, keeping the heading if the node does not set one."""
    return VehiclePose(
        target.x, target.y, pose.theta if target.theta is None else normalize_angle(target.theta)
    )


def target_of(node: Node) -> Target:
    position = node.node_position
    assert position is not None  # acceptance rejected orders with nodes we cannot locate
    return Target.of(
        position.x,
        position.y,
        position.theta,
        position.allowed_deviation_xy,
        position.allowed_deviation_theta,
    )


class Drive:
    """The robot's motion: its pose, its velocity, whether it drives, and what keeps it standing
    (``paused`` by startPause, ``teleop`` by startTeleop)."""

    def __init__(self, pose: VehiclePose, settings: SimulationSettings, outbox: Outbox) -> None:
        self.pose = pose
        self.velocity = (0.0, 0.0, 0.0)
        self.driving = False
        self.paused = False
        self.teleop = False
        self._settings = settings
        self._outbox = outbox

    def step_length(self, edge: Edge | None) -> float:
        """How far one tick goes: ``speed * tick_period``, less if the edge's ``maxSpeed`` is lower."""
        settings = self._settings
        if edge is not None and edge.max_speed is not None and 0 < edge.max_speed < settings.speed:
            return edge.max_speed * settings.tick_period
        return settings.step

    def set_motion(self, start: VehiclePose, *, driving: bool) -> None:
        """Velocity in the vehicle frame from this tick's step; a change of ``driving`` is an event."""
        if driving:
            period = self._settings.tick_period
            pose = self.pose
            dx, dy = (pose.x - start.x) / period, (pose.y - start.y) / period
            cos, sin = math.cos(start.theta), math.sin(start.theta)
            omega = angle_difference(pose.theta, start.theta) / period
            self.velocity = (dx * cos + dy * sin, -dx * sin + dy * cos, omega)
        else:
            self.velocity = (0.0, 0.0, 0.0)
        if driving != self.driving:
            self.driving = driving
            self._outbox.state_changed = True

    def stop(self) -> None:
        self.driving = False
        self.velocity = (0.0, 0.0, 0.0)
        self._outbox.state_changed = True

    def velocity_model(self) -> Velocity:
        vx, vy, omega = self.velocity
        return Velocity(vx=vx, vy=vy, omega=omega)
