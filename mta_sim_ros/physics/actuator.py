"""Steering actuator: makes the steering angle psi_1 a smooth state (MODEL.md, Dynamics).

The kinetic energy depends on psi_1, so a step in psi_1 would be an impulse: the command goes
through a first-order lag with a rate limit, as a hydraulic steering cylinder behaves.
"""
from __future__ import annotations

from .spec import Actuator


def steering_rate(act: Actuator, psi1: float, command: float) -> float:
    """psi_1' = clip((clip(command, +-max_angle) - psi_1) / time_constant, +-max_rate), rad/s."""
    target = min(max(command, -act.max_angle), act.max_angle)
    rate = (target - psi1) / act.time_constant
    return min(max(rate, -act.max_rate), act.max_rate)
