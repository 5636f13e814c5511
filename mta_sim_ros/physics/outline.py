"""The train's outline: each cart drawn as a box (the markers, the URDF) and the envelope the
boxes sweep (the sweep's swept-width metric). From the train file alone, no state.

A cart's box runs along its axis from A_k back to the rearmost of B_k and its rear hitch point
A_{k+1}; it is as wide as :func:`cart_widths` says and BOX_HEIGHT high, standing on the ground.
"""
from __future__ import annotations

#: Width of a cart's outline when nothing says otherwise (the tractor, a cart without draft), m.
DEFAULT_WIDTH = 2.5
#: Height of every cart's box, m (the URDF's; the markers lie in z = 0).
BOX_HEIGHT = 2.0


def cart_widths(train) -> list[float]:
    """Width of each cart's outline, m: DEFAULT_WIDTH for the tractor; for a towed cart the
    widest ``Draft.width`` acting on it (the draft width is taken as metres), else
    DEFAULT_WIDTH."""
    widths = [DEFAULT_WIDTH]
    for cart in train.carts[1:]:
        drafts = [d.width for d in train.draft if d.cart == cart.name]
        widths.append(max(drafts, default=DEFAULT_WIDTH))
    return widths


def box_of(train, k: int) -> tuple[float, float, float, float]:
    """(centre x in the cart's frame, length, width, height) of cart k's box, m: from A_k (x = l_k,
    B_k at x = 0) back to the rearmost of B_k and A_{k+1} (x = -a_k)."""
    cart = train.carts[k]
    rear = min(0.0, -cart.hitch_offset)  # the rearmost of B_k (x = 0) and A_{k+1} (x = -a_k)
    return (cart.length + rear) / 2.0, cart.length - rear, cart_widths(train)[k], BOX_HEIGHT
