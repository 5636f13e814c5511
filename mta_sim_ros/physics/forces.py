"""The force elements grouped by the cart they act on (MODEL.md, "Force laws").

Resistances act at the rear axle centres B_k against v_Bk; traction acts at A_1 along v_A1. Each
element contributes F_e * kapP_e to the generalized force Q (kapP = d(point speed)/dV). On a tilted
plane rolling resistance takes the normal load m g cos(slope), and gravity's component in the plane
is a grade resistance at each centre of mass (``kernel/laws.py``: ``grade_resistance``).

The laws themselves are written once, in the kernel (``kernel/laws.py``: ``resistance``,
``traction_law``, ``steering_rate``), which every level calls, compiled or as plain Python; this
module only says which elements sit at which axle, for ``kernel.pack``.
"""
from __future__ import annotations

from dataclasses import dataclass

from .spec import Draft, Train
from .terrain import PlaneFrame


@dataclass(frozen=True)
class CartResistance:
    """All resistance elements acting at one cart's B_k: rolling f m g plus any drafts."""

    rolling: float  # N, sum of f m g of the rolling elements of this cart
    drafts: tuple[Draft, ...]


def cart_resistances(train: Train) -> tuple[CartResistance, ...]:
    """Group the train's rolling and draft elements by the cart they act on (cart order)."""
    out = []
    for cart in train.carts:
        rolling = sum(r.coefficient * cart.mass * train.gravity for r in train.rolling if r.cart == cart.name)
        if train.terrain is not None:  # the normal load on a tilted plane: m g cos(slope)
            rolling *= PlaneFrame.of(train.terrain).z[2]
        drafts = tuple(d for d in train.draft if d.cart == cart.name)
        out.append(CartResistance(rolling=rolling, drafts=drafts))
    return tuple(out)
