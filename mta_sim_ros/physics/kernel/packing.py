"""The train's constants as the kernels read them: one float64 array (``pack``), and a column of
it back (``column``). Plain Python, not compiled: the fields are declared in ``base.py``."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .. import forces
from ..terrain import PlaneFrame
from .base import CART, CART_SIZE, DRAFT, DRAFT_SIZE, HEAD, HEAD_SIZE, LAWS, C, H


def pack(train, law: str | None = None, traction=None) -> np.ndarray:
    """The constants of ``train`` as one float64 array: HEAD, then CART per cart, then DRAFT per
    draft (grouped by cart), then on a height grid its RELIEF block (relief.surface). ``law`` / ``traction`` override the train's traction law (the
    kinematic level packs law 'kinematic' and, for its inverse dynamics, 'prescribed_speed')."""
    traction = traction or train.traction
    law = law or traction.law
    if law not in LAWS:
        raise ValueError(f"traction law {law!r} has no kernel (one of {', '.join(LAWS)})")
    frame = PlaneFrame.of(train.terrain) if train.terrain is not None else None
    gravity = frame.gravity(train.gravity) if frame else (0.0, 0.0)
    drafts = [d for resistance in forces.cart_resistances(train) for d in resistance.drafts]
    relief = HEAD_SIZE + CART_SIZE * train.n + DRAFT_SIZE * len(drafts) if train.relief is not None else 0
    values = HEAD.values(SimpleNamespace(train=train, law=law, traction=traction, slope=frame is not None,
                                         gravity=gravity, relief=relief))
    drafts = []
    for k, (cart, resistance) in enumerate(zip(train.carts, forces.cart_resistances(train))):
        values += CART.values(SimpleNamespace(cart=cart, resistance=resistance, draft_first=len(drafts)))
        drafts += resistance.drafts
    for d in drafts:
        values += DRAFT.values(d)
    if train.relief is not None:  # the RELIEF block (relief.surface)
        ty, tx, coefficients = train.relief.spline
        values += [len(ty), len(tx), *ty, *tx, *coefficients]
    return np.array(values, dtype=np.float64)


def column(P: np.ndarray, name: str) -> tuple[float, ...]:
    """One CART field of every cart, read from the packed array (for the reference code)."""
    n, i = int(P[H.n]), getattr(C, name)
    return tuple(float(P[HEAD_SIZE + CART_SIZE * k + i]) for k in range(n))


def max_rate_of(P: np.ndarray, max_rate: float | None = None) -> float:
    """The steering rate limit held as an input: ``max_rate``, or None for the train's own."""
    return float(P[H.max_rate]) if max_rate is None else float(max_rate)


def shape_of(P: np.ndarray) -> tuple:
    """What the schemes of one batch (batched.py) share: the length of P, the number of carts, the
    traction law, each cart's drafts (first, count), whether a draft's speed is a switch, the
    terrain's kind, and which traction limits are infinite (the switching functions' layout)."""
    n = int(P[H.n])
    drafts = tuple((int(P[HEAD_SIZE + CART_SIZE * k + C.draft_first]), int(P[HEAD_SIZE + CART_SIZE * k + C.draft_count]))
                   for k in range(n))
    return (len(P), n, int(P[H.law]), drafts, bool(P[H.speed_switches]), bool(P[H.slope]), bool(P[H.relief]),
            bool(np.isinf(P[H.max_force])), bool(np.isinf(P[H.max_power])), bool(np.isinf(P[H.max_accel])))


def stack(columns) -> np.ndarray:
    """The packed constants of schemes of one shape (``shape_of``) side by side, a scheme a column:
    the P of batched.rhs_lanes. A height grid is not batched (its relief is read point by point)."""
    columns = [np.asarray(P, dtype=np.float64) for P in columns]
    if not columns:
        raise ValueError("a batch needs at least one scheme")
    first = shape_of(columns[0])
    for i, P in enumerate(columns[1:], start=1):
        if shape_of(P) != first:
            raise ValueError(f"scheme {i} has another shape than scheme 0 (carts, law, drafts, terrain or "
                             f"traction limits): {shape_of(P)} != {first}")
    if first[6]:
        raise ValueError("a train on a height grid is not batched (its relief is read point by point)")
    return np.ascontiguousarray(np.stack(columns, axis=1))
