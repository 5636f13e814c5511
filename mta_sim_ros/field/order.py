"""The order the swaths are driven in: cells, the order inside a cell, and where to begin.

**Cells** (a boustrophedon decomposition by the swaths themselves): going across the rows, a
row's pieces continue the cells of the row before when they are as many and each overlaps,
along the swaths' direction, the piece of the same rank in that row; otherwise (an obstacle or a
bay begins or ends) the open cells close and each piece starts a new one. A cell is then one
swath a row, side by side, so the turns inside it join neighbours.

**Orders** inside a cell: consecutive swaths are driven in opposite directions, each turn joining
two swaths some spacings apart; a U-turn needs at least ``min_u`` (turns.py), so an order whose
every turn spans m spacings or more, m spacings >= min_u, needs no tighter turn.

- ``boustrophedon`` (m = 1): the swaths side by side.
- ``skip`` (skip one, m = 2): Fields2Cover's snake, out on every other swath and back on the rest,
  with its turnaround made wide: out 0, 2, ..., a - 2 (a = count - 4), then a + 2, a, a + 3, a + 1,
  then back a - 1, ..., 1 (odd counts alike): every turn spans 2 spacings but two of 3 and one of 4.
- ``skipK`` (skip K, m = K + 1 >= 3): blocks of 2m swaths, the last one taking what is left
  (2m to 4m - 1), each driven interleaved: h, 0, h + 1, 1, ..., 2h - 1, h - 1 for an even block of
  2h, 0, h, 1, h + 1, ..., 2h - 2, h - 1 for an odd one of 2h - 1: every turn spans h - 1 to h + 1
  spacings (>= m), a block's first swath is h + h' + 1 or more from the last one's end.
A cell of fewer than 2m swaths has no such order (its middle swath is closer than m to all the
rest): it is driven out and back by lanes (r, r + m, ..., then the next lane back), and the turns
that join closer swaths are tight. ``auto`` takes, over the whole field, the order with the fewest
turns tighter than min_u, the smaller m on a tie: a field whose boustrophedon turns are all U's
gets boustrophedon.

**Cells in turn**: from the entry, the nearest start of a cell not yet worked next (a cell can be
driven from its first or its last row, and the first swath either way), the cells joined by
transits.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .swaths import Swath

#: the orders by the spacings m every turn spans at least: boustrophedon 1, skip 2, skipK K + 1
ORDERS = ("boustrophedon", "skip", *(f"skip{k}" for k in range(2, 10)))


@dataclass(frozen=True)
class Pass:
    """A swath as driven: its direction and its place in the cell."""

    swath: Swath
    forward: bool  # driven along the plan's angle (+u) or against it

    @property
    def start(self) -> np.ndarray:
        c = self.swath.line.coords
        return np.array(c[0] if self.forward else c[-1])

    @property
    def end(self) -> np.ndarray:
        c = self.swath.line.coords
        return np.array(c[-1] if self.forward else c[0])


def cells(swaths) -> list[list[Swath]]:
    """The swaths grouped into cells (module docstring), each a list with one swath a row."""
    rows: dict[int, list[Swath]] = {}
    for sw in swaths:
        rows.setdefault(sw.row, []).append(sw)
    done: list[list[Swath]] = []
    open_cells: list[list[Swath]] = []
    for row in sorted(rows):
        pieces = sorted(rows[row], key=lambda sw: sw.start)
        joined = len(pieces) == len(open_cells) and all(
            p.start < c[-1].end and c[-1].start < p.end for p, c in zip(pieces, open_cells))
        if joined:
            for p, c in zip(pieces, open_cells):
                c.append(p)
        else:
            done.extend(open_cells)
            open_cells = [[p] for p in pieces]
    done.extend(open_cells)
    return done


def spans(order: str) -> int:
    """m: the spacings every turn of ``order`` spans at least (a cell of 2m swaths or more)."""
    if order == "boustrophedon":
        return 1
    return 2 if order == "skip" else int(order[4:]) + 1


def sequence(order: str, count: int) -> list[int]:
    """The ranks of a cell's ``count`` swaths in the order driven (module docstring)."""
    m = spans(order)
    if m == 1:
        return list(range(count))
    if count < 2 * m:
        return lanes(count, m)
    if m == 2:
        a = count - 4
        return list(range(0, a, 2)) + [a + 2, a, a + 3, a + 1] + list(range(a - 1 - (a % 2 == 1), 0, -2))
    out, base = [], 0
    while base < count:
        size = count - base if count - base < 4 * m else 2 * m
        out.extend(base + r for r in interleaved(size))
        base += size
    return out


def interleaved(size: int) -> list[int]:
    """A block of ``size`` swaths: h, 0, h + 1, 1, ... (even) or 0, h, 1, h + 1, ... (odd)."""
    h = (size + 1) // 2
    if size % 2 == 0:
        return [r for i in range(h) for r in (h + i, i)]
    return [r for i in range(h - 1) for r in (i, h + i)] + [h - 1]


def lanes(count: int, m: int) -> list[int]:
    """Lane r = r, r + m, ... driven out, the next lane back, and so on."""
    out = []
    for r in range(min(m, count)):
        lane = list(range(r, count, m))
        out.extend(lane if r % 2 == 0 else lane[::-1])
    return out


def tight_turns(order: str, cell: list[Swath], min_width: float) -> int:
    """Turns of ``order`` in ``cell`` that join swaths closer than ``min_width``."""
    ranks = sequence(order, len(cell))
    return sum(abs(cell[b].offset - cell[a].offset) < min_width * (1.0 - 1e-9) for a, b in zip(ranks, ranks[1:]))


def choose_order(asked: str, all_cells: list[list[Swath]], min_width: float, spacing: float) -> tuple[str, str]:
    """(the order, why) for ``asked`` (auto or one of ORDERS): auto tries the orders up to the
    one whose m spacings hold ``min_width``."""
    if asked != "auto":
        return asked, "asked"
    need = max(1, math.ceil(min_width / spacing * (1.0 - 1e-9)))
    tried = [o for o in ORDERS if spans(o) <= need] or [ORDERS[-1]]
    tight = {order: sum(tight_turns(order, c, min_width) for c in all_cells) for order in tried}
    best = min(tried, key=lambda o: (tight[o], spans(o)))
    counts = ", ".join(f"{o} {tight[o]}" for o in tried)
    return best, f"auto: fewest turns narrower than the narrowest U, {min_width:.1f} m ({counts})"


def variants(cell: list[Swath], order: str) -> list[list[Pass]]:
    """The four ways to drive a cell: from its first or its last row, the first swath either way."""
    ranks = sequence(order, len(cell))
    out = []
    for ranks_used in (ranks, [len(cell) - 1 - r for r in ranks]):
        for first in (True, False):
            out.append([Pass(cell[r], first == (i % 2 == 0)) for i, r in enumerate(ranks_used)])
    return out


def route_cells(all_cells: list[list[Swath]], order: str, entry) -> list[list[Pass]]:
    """The cells in the order driven, each as its passes, nearest start first from ``entry``."""
    left = list(range(len(all_cells)))
    here = np.asarray(entry, dtype=float)
    out = []
    while left:
        best = None
        for c in left:
            for passes in variants(all_cells[c], order):
                d = float(np.hypot(*(passes[0].start - here)))
                if best is None or d < best[0] - 1e-9:
                    best = (d, c, passes)
        _, c, passes = best
        out.append(passes)
        left.remove(c)
        here = passes[-1].end
    return out


def swath_heading(angle: float, forward: bool) -> float:
    return angle if forward else angle + math.pi
