"""L-shaped motion: along X, then along Y, then turn on the spot, as Isaac's reference simulator does."""

from __future__ import annotations

import math
from dataclasses import dataclass

DEFAULT_DEVIATION_XY = 0.05  # m, used when a node's allowedDeviationXY is missing or 0
DEFAULT_DEVIATION_THETA = 0.01  # rad, used when a node's allowedDeviationTheta is missing or 0


@dataclass(frozen=True)
class Pose:
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

    def within_xy(self, pose: Pose) -> bool:
        return math.hypot(self.x - pose.x, self.y - pose.y) <= self.deviation_xy

    def reached_by(self, pose: Pose) -> bool:
        if not self.within_xy(pose):
            return False
        return self.theta is None or abs(angle_difference(self.theta, pose.theta)) <= self.deviation_theta


def angle_difference(to: float, frm: float) -> float:
    """Signed shortest turn from ``frm`` to ``to``, in [-pi, pi]."""
    return math.atan2(math.sin(to - frm), math.cos(to - frm))


def normalize_angle(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def step_towards(pose: Pose, target: Target, step: float) -> Pose:
    """One tick of motion: at most ``step`` metres along X (then Y), or ``step`` radians of turning."""
    if not target.within_xy(pose):
        dx = target.x - pose.x
        if dx != 0:
            return Pose(pose.x + math.copysign(min(abs(dx), step), dx), pose.y, pose.theta)
        dy = target.y - pose.y
        return Pose(pose.x, pose.y + math.copysign(min(abs(dy), step), dy), pose.theta)
    if target.theta is None:
        return pose
    turn = angle_difference(target.theta, pose.theta)
    return Pose(pose.x, pose.y, normalize_angle(pose.theta + math.copysign(min(abs(turn), step), turn)))


def jump_to(pose: Pose, target: Target) -> Pose:
    """Instant mode: be at the node, keeping the heading if the node does not set one."""
    return Pose(target.x, target.y, pose.theta if target.theta is None else normalize_angle(target.theta))
