"""The kinematic chain inverted: the train's pose and steering that keep a point of one cart
exactly on a given path. The controller's feedforward (controllers/implement/loop.py) and the
field planner's checks of a turn (field/turning.py) both read it, so it lives here, once.

The path is the one a point P of cart ``cart`` runs along: P is ``offset`` m ahead of the cart's
axle B_m on its axis. Its samples come as separate arrays (x, y, heading of travel, reversed 0/1,
the last vertex of each sample's direction stretch), so any caller can hand them in.

Each cart's heading follows from the path of the point it carries: the axle's velocity is along
the axis, so d th / d tau = sin(phi - th) / o with phi P's direction of motion and tau its distance
along the path (cart-aligned: both turned by pi reversing); along a chord phi is constant and
tan((th - phi) / 2) = tan((th0 - phi) / 2) exp(-tau / o), exact. The sweep runs the way this decays
(towards growing tau for o > 0): a point ahead of the axle follows its past, one behind it is led
by its future, which is known here. Up the chain from cart m to the tractor (each cart carries the
next one's hitch, a_k behind its axle), whose front axle's path gives the steering; down the
chain the carts behind cart m follow its rear hitch.
"""
from __future__ import annotations

import math

import numpy as np

from ...jit import entry, jitable
from .base import CART_SIZE, HEAD_SIZE, C, H, wrap_angle


@jitable
def chord(px, py, i, flip):
    """(direction + flip, length) of the chord from sample i to i + 1."""
    dx, dy = px[i + 1] - px[i], py[i + 1] - py[i]
    return math.atan2(dy, dx) + flip, math.sqrt(dx * dx + dy * dy)


@jitable
def carried(px, py, a, b, reverse, o, theta):
    """theta[a..b]: the headings of a cart that carries the point (samples px, py a..b of one
    direction stretch) ``o`` m ahead of its axle on its axis (module docstring). o = 0: the
    chord's own direction."""
    flip = math.pi if reverse else 0.0
    sense = -1.0 if reverse else 1.0
    if o == 0.0:
        for i in range(a, b):
            theta[i] = chord(px, py, i, flip)[0]
        theta[b] = theta[b - 1]
        return
    if (o > 0.0) != reverse:  # sweep towards growing index
        theta[a] = chord(px, py, a, flip)[0]
        for i in range(a, b):
            phi, length = chord(px, py, i, flip)
            theta[i + 1] = phi + 2.0 * math.atan(math.tan(0.5 * wrap_angle(theta[i] - phi))
                                                 * math.exp(-sense * length / o))
        return
    theta[b] = chord(px, py, b - 1, flip)[0]
    for i in range(b - 1, a - 1, -1):
        phi, length = chord(px, py, i, flip)
        theta[i] = phi + 2.0 * math.atan(math.tan(0.5 * wrap_angle(theta[i + 1] - phi)) * math.exp(sense * length / o))


@jitable
def inverse_stretch(P, x, y, heading, reverse, a, b, cart, offset, th, px, py, ref):
    """``inverse_chain`` on the direction stretch of vertices a..b."""
    n = int(P[H.n])
    back = reverse[a] != 0.0
    for i in range(a, b + 1):
        px[i], py[i] = x[i], y[i]
    for k in range(cart, -1, -1):  # up the chain: cart k carries the point at px, py
        bk = HEAD_SIZE + CART_SIZE * k
        o = offset if k == cart else -P[bk + C.hitch_offset]
        carried(px, py, a, b, back, o, th[:, k])
        for i in range(a, b + 1):  # on to A_k: back along the axis to B_k, then forward l_k
            e = P[bk + C.length] - o
            px[i], py[i] = px[i] + e * math.cos(th[i, k]), py[i] + e * math.sin(th[i, k])
    flip = math.pi if back else 0.0
    for i in range(a, b + 1):  # the steering: A_1's direction of motion against the tractor's axis
        lo, hi = (i - 1 if i > a else a), (i + 1 if i < b else b)
        course = math.atan2(py[hi] - py[lo], px[hi] - px[lo]) + flip
        ref[i, n] = wrap_angle(course - th[i, 0])
    for k in range(cart + 1, n):  # down the chain: cart k is pulled at A_k, l_k ahead of its axle
        bp = HEAD_SIZE + CART_SIZE * (k - 1)
        for i in range(a, b + 1):  # A_k = B_{k-1} - a_{k-1} e_{k-1}
            hitch = P[bp + C.hitch_offset]
            if k - 1 == cart:
                bx = x[i] - offset * math.cos(th[i, cart])
                by = y[i] - offset * math.sin(th[i, cart])
            else:
                bx, by = px[i], py[i]
            px[i], py[i] = bx - hitch * math.cos(th[i, k - 1]), by - hitch * math.sin(th[i, k - 1])
        bk = HEAD_SIZE + CART_SIZE * k
        carried(px, py, a, b, back, P[bk + C.length], th[:, k])
        for i in range(a, b + 1):  # to B_k
            px[i], py[i] = px[i] - P[bk + C.length] * math.cos(th[i, k]), py[i] - P[bk + C.length] * math.sin(th[i, k])
    for i in range(a, b + 1):
        ref[i, 0] = wrap_angle(th[i, 0] - heading[i] - flip)
        for k in range(1, n):
            ref[i, k] = wrap_angle(th[i, k - 1] - th[i, k])


@jitable
def inverse_chain(P, x, y, heading, reverse, end, cart, offset, ref):
    """The train's pose that keeps the point (``cart``, ``offset``) exactly on the path (x, y) at
    every vertex, into ``ref`` (m x (n + 1)): th_1 against the path's heading (cart-aligned), the
    hitch angles phi_2..phi_n, the steering psi_1 (module docstring). ``end[i]``: the last vertex
    of vertex i's direction stretch. Exact for the model's no-slip kinematics up to the path's
    sampling (each chord's direction taken at its midpoint)."""
    m = x.shape[0]
    n = int(P[H.n])
    th = np.empty((m, n))
    px, py = np.empty(m), np.empty(m)
    a = 0
    while a < m - 1:
        b = int(end[a])
        inverse_stretch(P, x, y, heading, reverse, a, b, cart, offset, th, px, py, ref)
        a = b


@entry
def inverse_of(P, x, y, heading, reverse, end, cart, offset):
    """``inverse_chain``'s (m x (n + 1)) array, compiled (the field planner's checks of a turn)."""
    ref = np.empty((x.shape[0], int(P[H.n]) + 1))
    inverse_chain(P, x, y, heading, reverse, end, cart, offset, ref)
    return ref
