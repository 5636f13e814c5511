"""The axles' static normal loads and their grip margin: the lateral force a no-slip axle must
give (a constraint force of the model, kernel.drawbar_pulls) against what friction can give.

Static normal loads, from the last cart forward (normal to the plane, weights m_k g cos(slope)):
cart k rests on its axle at B_k and its hitch at A_k = B_k + l_k e_k, and carries at its rear hitch
A_{k+1} = B_k - a_k e_k the load V_{k+1} the cart behind puts on it. Moments about B_k and the
vertical balance give

    V_k = (W_k c_k - V_{k+1} a_k) / l_k      (the hitch's share, passed on to the cart in front)
    N_Bk = W_k + V_{k+1} - V_k

and for the tractor V_1 is its front axle's load. Static: the load transfer between axles by the
grade (the weight's component along the ground at the centre of mass's height), the pull and the
turn, and between wheels, are left out (the tip margin, terrain.tip_margin, has the grade's and
the pull's for the tractor).

Grip margin of an axle with normal load N and lateral force F: 1 - |F| / (mu N), mu the train's
``lateral_friction``: 1 with no lateral force, 0 where the tyres would have to give all the
friction there is, negative past it. There the no-slip model does not hold: the axle slides
sideways, which the slip level (its tyres' drift) represents and the other levels do not.
"""
from __future__ import annotations

import numpy as np

from .terrain import PlaneFrame


def weights(train) -> np.ndarray:
    """Each cart's weight normal to the train's plane, m_k g cos(slope), N."""
    g = train.gravity * (PlaneFrame.of(train.terrain).z[2] if train.terrain is not None else 1.0)
    return np.array([cart.mass * g for cart in train.carts])


def hitch_loads(train) -> np.ndarray:
    """V_k of the module docstring, N, k = 1..n (index 0: the tractor's front axle, index k: the
    load cart k + 1 puts on the hitch behind cart k), then 0 (nothing behind the last cart)."""
    w = weights(train)
    loads = np.zeros(train.n + 1)
    for k in range(train.n - 1, -1, -1):
        cart = train.carts[k]
        loads[k] = (w[k] * cart.com_offset - loads[k + 1] * cart.hitch_offset) / cart.length
    return loads


def static_axle_loads(train) -> tuple[float, np.ndarray]:
    """(the tractor's front axle at A_1, each cart's axle at B_k), N, on the train's plane (the
    module docstring); they add up to sum m_k g cos(slope)."""
    hitch = hitch_loads(train)
    return float(hitch[0]), weights(train) + hitch[1:] - hitch[:-1]


def grip_margins(train, front_lateral, lateral, loads=None) -> np.ndarray:
    """The grip margin (the module docstring) of every no-slip axle: columns the tractor's front
    axle, then each cart's at B_k; rows those of ``front_lateral`` (rows) and ``lateral`` (rows x
    carts), N. NaN everywhere when the train gives no lateral_friction; -inf at an axle with no
    load (N <= 0) that must give a lateral force. ``loads``: static_axle_loads(train), if known."""
    forces = np.column_stack([np.asarray(front_lateral, dtype=float), np.asarray(lateral, dtype=float)])
    if train.lateral_friction is None:
        return np.full(forces.shape, np.nan)
    front, rear = static_axle_loads(train) if loads is None else loads
    grip = train.lateral_friction * np.concatenate(([front], rear))
    unloaded = np.where(forces == 0, 0.0, np.where(np.isnan(forces), np.nan, np.inf))
    ratio = np.where(grip > 0, np.abs(forces) / np.where(grip > 0, grip, 1.0), unloaded)
    return 1.0 - ratio
