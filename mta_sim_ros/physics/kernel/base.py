"""What every compiled file of the train's kernel shares: the layout of its arrays and small pieces.

The kernel (this package, ``integrate/rk.py``, ``run/whole.py``, ``run/offsets.py``) works on one flat
float64 array of the train's constants ``P`` and the state array, in the subset of Python numba
compiles (``jit.py``: the two lives of each function, and why every compiled file reads names only
from other compiled files). This file declares, once each:

    the packed constants   HEAD, CART and DRAFT: each field's name, meaning and value; ``packing.pack``
                           writes them and every index the kernels read (H, C, D) is derived from them
    the law codes          LAWS: the traction law of P (KINEMATIC: the kinematic level, no forces)
    the branch codes       NATURAL, LOW, HIGH: a non-smooth law left to the state or held on a side
    the record columns     what ``motion.rhs`` and ``motion.outputs`` write per cart and per run

State layout (dynamics.StateLayout): x_A1, y_A1, th_1..th_n, psi_1, V, z (index n + 4: the
governor's integral, or the kinematic level's ramp slope V').
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ...jit import jitable
from .vmath import pick

#: km/h per m/s (the ASABE draft law takes the speed in km/h)
MS_TO_KMH = 3.6


# -- the packed constants: each field declared once ------------------------------------------------

class Fields:
    """A block of P: (name, meaning, value from a context) per field. ``index`` is the named tuple
    of offsets the kernels read (``P[b + CART.index.mass]``), ``values(ctx)`` the numbers ``pack``
    writes. A named tuple of ints, not an IntEnum: numba compiles a global tuple's fields as
    constants on every version, while numba 0.59 (Ubuntu 24.04's) cannot index an array by an
    IntEnum member (0.68 can)."""

    def __init__(self, block: str, rows):
        self.block = block
        self.rows = tuple(rows)
        names = [name for name, _, _ in self.rows]
        self.index = namedtuple(block, names)(*range(len(names)))
        self.size = len(self.rows)
        self.meaning = {name: meaning for name, meaning, _ in self.rows}

    def values(self, ctx) -> list[float]:
        return [float(value(ctx)) for _, _, value in self.rows]


#: traction law codes; KINEMATIC is the kinematic level (speed prescribed, no forces in y')
CONSTANT, GOVERNOR, PRESCRIBED, KINEMATIC = 0, 1, 2, 3
LAWS = {"constant": CONSTANT, "governor": GOVERNOR, "prescribed_speed": PRESCRIBED, "kinematic": KINEMATIC}

HEAD = Fields("Head", (
    ("n", "number of carts n", lambda s: s.train.n),
    ("law", "traction law code (LAWS)", lambda s: LAWS[s.law]),
    ("smoothing_speed", "v0 of the resistances' tanh(v / v0) through v = 0, m/s", lambda s: s.train.smoothing_speed),
    ("time_constant", "steering actuator time constant tau, s", lambda s: s.train.actuator.time_constant),
    ("max_rate", "steering actuator rate limit, rad/s", lambda s: s.train.actuator.max_rate),
    ("max_angle", "steering angle limit, rad", lambda s: s.train.actuator.max_angle),
    ("force", "constant law: F_A1, N", lambda s: s.traction.force),
    ("max_force", "governor: adhesion limit of F_A1, N", lambda s: s.traction.max_force),
    ("max_power", "governor: engine power limit of F_A1 |V|, W", lambda s: s.traction.max_power),
    ("kp", "governor: proportional gain, N per m/s", lambda s: s.traction.kp),
    ("ki", "governor: integral gain, N per m", lambda s: s.traction.ki),
    ("windup_time", "governor: back-calculation anti-windup time, s", lambda s: s.traction.windup_time),
    ("response_time", "prescribed speed: first-order lag, s", lambda s: s.traction.response_time),
    ("max_accel", "prescribed speed: acceleration limit, m/s^2", lambda s: s.traction.max_accel),
    ("speed_switches", "1 when a draft grows with |speed| (ASABE B != 0): its speed's sign is a switch",
     lambda s: any(d.B != 0.0 for d in s.train.draft)),
    ("slope", "1 on a tilted plane (the train's terrain): every cart has a grade resistance", lambda s: s.slope),
    ("gravity_x", "gravity's component along the plane's x axis, m/s^2 (0 on the level)", lambda s: s.gravity[0]),
    ("gravity_y", "gravity's component along the plane's y axis, m/s^2", lambda s: s.gravity[1]),
    ("gravity", "g, m/s^2", lambda s: s.train.gravity),
    ("relief", "index in P of the height grid's RELIEF block (relief.py), 0 without one", lambda s: s.relief),
))

CART = Fields("Cart", (
    ("length", "l_k, A_k to B_k, m", lambda s: s.cart.length),
    ("lam", "lambda_k = a_k / l_k", lambda s: s.cart.hitch_offset / s.cart.length),
    ("lam2", "lambda_k^2", lambda s: (s.cart.hitch_offset / s.cart.length) ** 2),
    ("mu", "mu_k = c_k / l_k", lambda s: s.cart.com_offset / s.cart.length),
    ("mu2", "mu_k^2", lambda s: (s.cart.com_offset / s.cart.length) ** 2),
    ("mass", "m_k, kg", lambda s: s.cart.mass),
    ("inertia", "J_k about C_k, kg m^2", lambda s: s.cart.yaw_inertia),
    ("rolling", "sum of the rolling elements' f m g at B_k, N", lambda s: s.resistance.rolling),
    ("draft_first", "index of this cart's first draft in the DRAFT block", lambda s: s.draft_first),
    ("draft_count", "number of drafts at this cart's B_k", lambda s: len(s.resistance.drafts)),
    ("max_hitch", "largest |hitch angle| of the coupling in front of this cart, rad", lambda s: s.cart.max_hitch_angle),
    ("com_offset", "c_k, B_k forward to C_k, m", lambda s: s.cart.com_offset),
    ("hitch_offset", "a_k, B_k back to A_{k+1}, m", lambda s: s.cart.hitch_offset),
))

DRAFT = Fields("Draft", (
    ("soil_factor", "F_i", lambda d: d.soil_factor),
    ("A", "ASABE D497 A, N per width per depth", lambda d: d.A),
    ("B", "B, per km/h", lambda d: d.B),
    ("C", "C, per (km/h)^2", lambda d: d.C),
    ("width", "W, m or rows/tools", lambda d: d.width),
    ("depth", "T, cm (1 for seeding tools)", lambda d: d.depth),
))

H, C, D = HEAD.index, CART.index, DRAFT.index
HEAD_SIZE, CART_SIZE, DRAFT_SIZE = HEAD.size, CART.size, DRAFT.size


# -- small pieces ---------------------------------------------------------------------------------

@jitable
def pymin(a, b):
    """Python's min(a, b): a unless b is strictly smaller (the same answer for -0.0 and NaN)."""
    return b if b < a else a


@jitable
def pymax(a, b):
    return b if b > a else a


#: a branch left to the state (natural), or held: LOW where the switching function is <= 0, HIGH > 0
NATURAL, LOW, HIGH = -1, 0, 1


TWO_PI = 2.0 * math.pi


@jitable
def wrap_angle(a):
    """a wrapped to [-pi, pi] (geometry.wrap_angle; exact inside the interval)."""
    return pick((a >= -math.pi) & (a <= math.pi), a, a - TWO_PI * math.floor(a / TWO_PI + 0.5))  # no branch


@jitable
def no_mode():
    """No branch held: every law as the state is."""
    return np.empty(0, dtype=np.int64)


# -- what the kernels record ------------------------------------------------------------------------

#: columns of ``rec`` (rhs's record of each cart's chain factors, for the outputs); GRADE is the
#: cart's grade resistance referred to V (``laws.grade_resistance``), 0 on the level
KAPT, KAPB, KAPC, PSI, RES, KAPT_DOT, KAPB_DOT, GRADE = range(8)
REC = 8

#: the drawbar pull at A_k and the lateral force of the axle at B_k (written by ``drawbar_pulls``
#: only, after ``outputs``: the node's tick, which publishes neither, does not compute them)
AX, AY, BX, BY, CX, CY, PHI, VC, VB, VT, PULL, LAT = range(REC, REC + 12)
OUT = REC + 12
#: scalar outputs (FRONT_LAT: the lateral force of the tractor's front axle, ``drawbar_pulls``)
REAR_X, REAR_Y, TRACTION, MASS, RES_POWER, MARGIN, STEERING_RATE, GRADE_POWER, FRONT_LAT = range(9)
SCALARS = 9

#: most switching functions ``switches`` writes beyond the per-cart ones
FORCE_SWITCHES = 3
