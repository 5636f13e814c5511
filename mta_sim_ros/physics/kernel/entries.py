"""The train kernel's entry points: compiled and cached on disk (``jit.entry``), each with its
plain-Python twin as ``.py_func``. Python calls these; they call ``motion`` and ``laws``."""
from __future__ import annotations

import numpy as np

from ...jit import entry
from .base import FORCE_SWITCHES, HIGH, LOW, NATURAL, OUT, REC, SCALARS, H, no_mode
from .laws import actuator_release, branches
from .motion import drawbar_pulls, margin, outputs, rhs, switches
from .relief import off_relief, surface


@entry
def rhs_of(P, y, command, v_set, max_rate):
    """y' as a new array (dynamics.Model.rhs)."""
    dy = np.empty(y.shape[0])
    rhs(P, y, command, v_set, max_rate, dy, np.empty((0, REC)), no_mode())
    return dy


@entry
def held_rhs_of(P, y, command, v_set, max_rate, mode):
    """y' with the branches ``mode`` held (see ``rhs``, ``mode_of``)."""
    dy = np.empty(y.shape[0])
    rhs(P, y, command, v_set, max_rate, dy, np.empty((0, REC)), mode)
    return dy


@entry
def mode_of(P, y, command, v_set, rate_limited):
    """The branches of every law at y: the actuator's (HIGH while ``rate_limited``), then each
    switching function's (``branches``)."""
    g = np.empty(FORCE_SWITCHES + int(P[H.n]) + 1)
    mode = np.full(g.shape[0] + 1, NATURAL, dtype=np.int64)
    branches(g, switches(P, y, command, v_set, g), mode)
    mode[0] = HIGH if rate_limited else LOW
    return mode


@entry
def outputs_of(P, y, command, v_set, max_rate):
    """(cart n x OUT, scalars SCALARS) of ``outputs``."""
    n = int(P[H.n])
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    outputs(P, y, command, v_set, max_rate, cart, sc, np.empty(y.shape[0]))
    return cart, sc


@entry
def pulls_of(P, y, command, v_set, max_rate):
    """(cart n x OUT, scalars) of ``outputs`` with the drawbar pulls' and the axles' lateral forces
    (``drawbar_pulls``)."""
    n = int(P[H.n])
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    dy = np.empty(y.shape[0])
    outputs(P, y, command, v_set, max_rate, cart, sc, dy)
    drawbar_pulls(P, y, dy[n + 3], cart, sc)
    return cart, sc


@entry
def margin_of(P, y):
    """``margin``: (margin, cart index)."""
    return margin(P, y)


@entry
def switches_of(P, y, command, v_set):
    """The switching functions at y, as a new array."""
    g = np.empty(FORCE_SWITCHES + int(P[H.n]) + 1)
    m = switches(P, y, command, v_set, g)
    return g[:m].copy()


@entry
def release_of(P, psi1, command, max_rate):
    """``actuator_release``."""
    return actuator_release(P, psi1, command, max_rate)


@entry
def surface_of(block, x, y):
    """``relief.surface`` of a RELIEF block alone (terrain.HeightGrid.at): (z, dz/dx, dz/dy)."""
    return surface(block, 0, x, y)


@entry
def surfaces_of(block, xs, ys):
    """``surface_of`` at each point of the flat arrays xs, ys: (z, dz/dx, dz/dy) arrays."""
    z, zx, zy = np.empty(xs.shape[0]), np.empty(xs.shape[0]), np.empty(xs.shape[0])
    for i in range(xs.shape[0]):
        z[i], zx[i], zy[i] = surface(block, 0, xs[i], ys[i])
    return z, zx, zy


@entry
def off_relief_of(P, y):
    """``relief.off_relief``: the first cart off the height grid, -1 for none."""
    return off_relief(P, y)
