"""The order the swaths are driven in: cells, the order inside a cell, and where to begin.

**Cells** (a boustrophedon decomposition by the swaths themselves): going across the rows, a
row's pieces continue the cells of the row before when they are as many and each overlaps,
along the swaths' direction, the piece of the same rank in that row; otherwise (an obstacle or a
bay begins or ends) the open cells close and each piece starts a new one. A cell is then one
swath a row, side by side, so the turns inside it join neighbours.

**Orders** inside a cell (Fields2Cover's names): ``boustrophedon`` drives the swaths side by side;
``skip`` (Fields2Cover's snake order) drives every other one out, 0, 2, 4, ..., and the rest back,
..., 5, 3, 1: the turns span two spacings, but one (where it comes back) spans one. ``auto``
takes, over the whole field, the order with the fewest turns too tight for a U (spacing < 2R),
boustrophedon on a tie: a field where boustrophedon's turns are all U's gets boustrophedon.
Consecutive swaths are driven in opposite directions.

**Cells in turn**: from the entry, the nearest start of a cell not yet worked next (a cell can be
driven from its first or its last row, and the first swath either way), the cells joined by
transits.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .swaths import Swath

ORDERS = ("boustrophedon", "skip")


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


def sequence(order: str, count: int) -> list[int]:
    """The ranks of a cell's ``count`` swaths in the order driven."""
    if order == "skip":
        return list(range(0, count, 2)) + list(range(count - 1 - (count % 2 == 1), 0, -2))
    return list(range(count))


def tight_turns(order: str, cell: list[Swath], radius: float) -> int:
    """Turns of ``order`` in ``cell`` that join swaths closer than 2 ``radius``."""
    ranks = sequence(order, len(cell))
    return sum(abs(cell[b].offset - cell[a].offset) < 2.0 * radius * (1.0 - 1e-12) for a, b in zip(ranks, ranks[1:]))


def choose_order(asked: str, all_cells: list[list[Swath]], radius: float) -> tuple[str, str]:
    """(the order, why) for ``asked`` (auto or one of ORDERS)."""
    if asked != "auto":
        return asked, "asked"
    tight = {order: sum(tight_turns(order, c, radius) for c in all_cells) for order in ORDERS}
    best = min(ORDERS, key=lambda o: (tight[o], ORDERS.index(o)))
    counts = ", ".join(f"{o} {tight[o]}" for o in ORDERS)
    return best, f"auto: fewest turns tighter than a U of the train's radius ({counts})"


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
