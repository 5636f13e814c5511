"""What the simulator reports at one instant, from a state of any fidelity level.

Every level reports through its own ``outputs`` (levels.Level). The dynamic and kinematic levels
call ``kernel_outputs`` (``kernel.outputs``: one pass, compiled where numba runs);
``reference_outputs`` builds the same numbers from the readable reference (chain.py,
``dynamics.Model.terms``, geometry.py, guards.py): algorithm 1's path, and what the tests hold the
kernel to. The slip level builds its own.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernel
from .geometry import cart_points, hitch_angles


@dataclass
class Outputs:
    """What the simulator reports at one instant (SI units, rad)."""

    t: float  # s
    front: np.ndarray  # A_k, n x 2
    axle: np.ndarray  # B_k, n x 2
    com: np.ndarray  # C_k, n x 2
    rear_hitch: np.ndarray  # A_{n+1} (the last cart's rear hitch point), 2
    heading: np.ndarray  # th_k, n
    hitch_angle: np.ndarray  # th_{k-1} - th_k, n - 1
    psi: np.ndarray  # psi_k, n (psi_1 = applied steering angle)
    com_speed: np.ndarray  # s'_Ck, n, m/s
    axle_speed: np.ndarray  # s'_Bk, n, m/s
    yaw_rate: np.ndarray  # th'_k, n, rad/s
    speed: float  # V = s'_A1, m/s
    steering: float  # psi_1, rad
    steering_rate: float  # psi_1', rad/s: the actuator's rate under the held command and rate limit
    command: float  # steering command held over the last tick, rad
    speed_setpoint: float  # m/s
    resistance: np.ndarray  # F_Bk, n, N (> 0 opposes forward motion of B_k)
    traction: float  # F_A1, N
    power: float  # N = F_A1 V, W
    resistance_power: float  # sum F_Bk s'_Bk, W
    grade_power: float  # sum F_gk V, W: the rate of the carts' potential energy (0 on the level)
    kinetic_energy: float  # T = 1/2 M V^2, J
    jackknife_margin: float  # rad, see guards.jackknife_margin


def kernel_outputs(P: np.ndarray, t: float, y, command: float, v_set: float, max_rate: float,
                   law_input: float | None = None, compiled: bool = True) -> Outputs:
    """The Outputs of state y of a kernel level with packed constants P under the held input
    (command, v_set, max_rate). ``law_input`` is what the traction law of P reads in place of v_set
    (the kinematic level's inverse dynamics: ``KinematicModel.output_input``); ``compiled`` = False
    runs the kernel as plain Python (the same numbers)."""
    y = np.ascontiguousarray(y, dtype=np.float64)
    run = kernel.outputs_of if compiled else kernel.outputs_of.py_func
    cart, sc = run(P, y, float(command), float(v_set if law_input is None else law_input), float(max_rate))
    n = cart.shape[0]
    V = float(y[n + 3])
    traction = float(sc[kernel.TRACTION])
    return Outputs(
        t=t, front=cart[:, kernel.AX:kernel.AY + 1], axle=cart[:, kernel.BX:kernel.BY + 1],
        com=cart[:, kernel.CX:kernel.CY + 1], rear_hitch=sc[kernel.REAR_X:kernel.REAR_Y + 1],
        heading=y[2:2 + n].copy(), hitch_angle=cart[1:, kernel.PHI], psi=cart[:, kernel.PSI],
        com_speed=cart[:, kernel.VC], axle_speed=cart[:, kernel.VB], yaw_rate=cart[:, kernel.VT],
        speed=V, steering=float(y[n + 2]), steering_rate=float(sc[kernel.STEERING_RATE]), command=command,
        speed_setpoint=v_set,
        resistance=cart[:, kernel.RES], traction=traction, power=traction * V,
        resistance_power=float(sc[kernel.RES_POWER]), grade_power=float(sc[kernel.GRADE_POWER]),
        kinetic_energy=0.5 * float(sc[kernel.MASS]) * V * V,
        jackknife_margin=float(sc[kernel.MARGIN]))


def reference_outputs(model, t: float, y: np.ndarray, command: float, v_set: float,
                      max_rate: float | None = None) -> Outputs:
    """``kernel_outputs`` for a no-slip level, built from the readable reference path (its
    ``terms``)."""
    from .guards import JACKKNIFE_PSI

    L = model.layout
    tm = model.terms(y, command, v_set, max_rate)
    ch = tm.chain
    V = float(y[L.speed])
    heading = y[L.heading]
    pts = cart_points(model.train, float(y[L.x]), float(y[L.y]), heading)
    axle_speed = np.array(ch.kapB) * V
    resistance = np.array(tm.resistance)
    phis = hitch_angles(heading.tolist())
    margins = [min(cart.max_hitch_angle - abs(phi), JACKKNIFE_PSI - abs(psi))
               for cart, phi, psi in zip(model.train.carts[1:], phis, ch.psi[1:])]
    return Outputs(
        t=t,
        front=pts["A"], axle=pts["B"], com=pts["C"], rear_hitch=pts["rear_hitch"],
        heading=np.array(heading, dtype=float),
        hitch_angle=np.array(phis),
        psi=np.array(ch.psi),
        com_speed=np.array(ch.kapC) * V,
        axle_speed=axle_speed,
        yaw_rate=np.array(ch.kapT) * V,
        speed=V,
        steering=float(y[L.steering]),
        steering_rate=tm.steering_rate,
        command=command,
        speed_setpoint=v_set,
        resistance=resistance,
        traction=tm.traction,
        power=tm.traction * V,
        resistance_power=float(np.dot(resistance, axle_speed)),
        grade_power=float(sum(g * V for g in tm.grade)),
        kinetic_energy=0.5 * tm.mass * V * V,
        jackknife_margin=min(margins, default=float("inf")),
    )
