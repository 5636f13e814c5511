"""Two recorded runs compared: the largest difference of each output, the second run
interpolated onto the first one's times."""
from __future__ import annotations

import math

import numpy as np

from .bagdata import BagData, Series, wrap


def _interp(s: Series, t_rel: np.ndarray, t0: float, hold: bool) -> np.ndarray:
    """Values of ``s`` at times ``t_rel`` (relative to ``t0``): linear, or sample-and-hold."""
    ts = s.t - t0
    vals = s.values.reshape(len(ts), -1)
    if len(ts) == len(t_rel) and np.array_equal(ts, t_rel):
        return vals
    if hold:
        i = np.clip(np.searchsorted(ts, t_rel, side="right") - 1, 0, len(ts) - 1)
        return vals[i]
    return np.column_stack([np.interp(t_rel, ts, vals[:, j]) for j in range(vals.shape[1])])


def compare(a: BagData, b: BagData) -> list[dict]:
    """Largest differences b - a per output, after interpolating b onto a's times (relative to each
    bag's first pose) over the interval both cover. Continuous outputs are interpolated linearly,
    commands (held over each tick) sample-and-hold; headings and hitch angles are wrapped.
    Carts are matched by name; joints by the names of both carts.
    """
    rows = []
    ta = a.poses.t - a.t0
    tb_end = b.poses.t[-1] - b.t0
    common = ta[ta <= tb_end + 1e-12]

    def add(output, unit, diff, scale=1.0, at=None):
        at = common if at is None else at
        if diff.size == 0:
            return
        diff = np.abs(diff) * scale
        i = int(np.nanargmax(diff))
        rows.append({"output": output, "unit": unit, "max_abs_diff": float(diff[i]), "time_s": float(at[i])})

    ia = a.poses.t - a.t0 <= tb_end + 1e-12
    for k, name in enumerate(a.cart_names):
        if name not in b.cart_names:
            continue
        j = b.cart_names.index(name)
        pa = a.poses.values[ia, k]
        pb = _interp(Series(b.poses.t, b.poses.ns, b.poses.values[:, j]), common, b.t0, hold=False)
        add(f"A_{k + 1} position ({name})", "m", np.hypot(*(pb - pa).T))
        Ba, Bb = a.axles()[ia, k], b.axles()[:, j]
        add(f"B_{k + 1} position ({name})", "m",
            np.hypot(*(_interp(Series(b.poses.t, b.poses.ns, Bb), common, b.t0, False) - Ba).T))
        hb = _interp(Series(b.poses.t, b.poses.ns, np.unwrap(b.pose_heading.values[:, j])), common, b.t0, False)
        add(f"heading ({name})", "deg", wrap(hb[:, 0] - np.unwrap(a.pose_heading.values[:, k])[ia]), 180 / math.pi)
        for attr, label, unit in (("com_speed", "centre-of-mass speed", "m/s"), ("resistance", "resistance F_B", "N")):
            sa, sb = getattr(a, attr), getattr(b, attr)
            if sa is None or sb is None:
                continue
            sel = sa.t - a.t0 <= tb_end + 1e-12
            at = sa.t[sel] - a.t0
            vb = _interp(Series(sb.t, sb.ns, sb.values[:, j]), at, b.t0, False)[:, 0]
            add(f"{label} ({name})", unit, vb - sa.values[sel, k], at=at)
    ha, hb_all = a.hitch_angles(), b.hitch_angles()
    for k, (p, q) in enumerate(zip(a.cart_names, a.cart_names[1:])):
        if p in b.cart_names and q in b.cart_names and b.cart_names.index(q) == b.cart_names.index(p) + 1:
            j = b.cart_names.index(p)
            hb = _interp(Series(b.poses.t, b.poses.ns, np.unwrap(hb_all[:, j])), common, b.t0, False)[:, 0]
            add(f"hitch angle {p}-{q}", "deg", wrap(hb - np.unwrap(ha[:, k])[ia]), 180 / math.pi)
    for attr, label, unit, scale, hold in (("power", "traction power", "kW", 1e-3, False),
                                           ("command", "steering command", "deg", 180 / math.pi, True),
                                           ("applied", "applied steering", "deg", 180 / math.pi, False),
                                           ("setpoint", "speed set-point", "m/s", 1.0, True)):
        sa, sb = getattr(a, attr), getattr(b, attr)
        if sa is None or sb is None:
            continue
        sel = (sa.t - a.t0 <= tb_end + 1e-12) & (sa.t - a.t0 >= sb.t[0] - b.t0 - 1e-12)
        at = sa.t[sel] - a.t0
        vb = _interp(sb, at, b.t0, hold)[:, 0]
        add(label, unit, vb - sa.values[sel], scale, at=at)
    return rows
