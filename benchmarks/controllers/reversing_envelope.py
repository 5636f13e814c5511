"""The reversing controller's envelope on generated trains (``python -m benchmarks reversing``'s last
section): trains of 2 to 5 carts of random lengths, their hitches ahead of and behind their axles
(lanes_rhs.random_train), backed 100 m at -1 and -3 m/s from the check's start (envelope.start_scene:
0.5 m off the line, hitches +-2 deg). For each, the check's verdict (envelope.holding: the kinematic
loop with the actuator's limits) and the dynamic level's run with the same gain (controller.reverse:
held as the check holds its loop, envelope.run_holds: not stopped, and after 100 m the last axle
within 5 cm of the line, the hitches within 2 deg). A refusal that the dynamic run
holds would be a refusal without cause; an acceptance that folds, a check that is not sufficient.
Then ``held_design``'s choice (the default weights, else the first of controller.LADDER that the
check and the dynamic level hold) run on the dynamic level the same way."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..common import table

#: generated trains per number of carts, the numbers of carts and the speeds they back at
GENERATED = 12
CARTS, SPEEDS = (2, 3, 4, 5), (-1.0, -3.0)
HEADER = ["carts", "speed, m/s", "trains", "the check holds", "held on the dynamic level", "verdicts agree",
          "refused, and not held", "accepted, but not held", "held_design holds",
          "held on the dynamic level with its weights"]


def generated(per: int = GENERATED, seed: int = 20261207) -> tuple[list, dict]:
    """(table rows, {(carts, speed): (share the check holds, share held)})."""
    from mta_sim_ros.controllers.reversing import envelope
    from mta_sim_ros.controllers.reversing.controller import design, held_design, reverse
    from mta_sim_ros.validate import InputError

    from ..common import random_train

    rows, figures = [], {}
    for n in CARTS:
        rng = np.random.default_rng(seed + n)
        trains = [random_train(n, rng) for _ in range(per)]
        for speed in SPEEDS:
            checked = held = agree = refused_folds = accepted_fails = laddered = ladder_held = 0
            for train in trains:
                gains = design(train, speed, check=False)
                holds = envelope.holding(train, gains) == ""
                ok = held_on_dynamic(train, speed, gains)
                checked += holds
                held += ok
                agree += holds == ok
                refused_folds += not holds and not ok
                accepted_fails += holds and not ok
                try:
                    chosen = held_design(train, speed)
                except InputError:
                    continue
                laddered += 1
                ladder_held += ok if chosen.weights == gains.weights else held_on_dynamic(train, speed, chosen)
            rows.append((str(n), f"{speed:g}", str(per), str(checked), str(held), str(agree), str(refused_folds),
                         str(accepted_fails), str(laddered), str(ladder_held)))
            figures[(n, speed)] = (checked / per, held / per, laddered / per, ladder_held / per)
            print(rows[-1], flush=True)
    return rows, figures


def held_on_dynamic(train, speed: float, gains) -> bool:
    """The dynamic level's run with ``gains`` from the check's start, 100 m back, held as the check
    holds its own loop (envelope.run_holds: not stopped, at the end within 5 cm of the line and the
    hitches within 2 deg)."""
    from mta_sim_ros.controllers.reversing import envelope
    from mta_sim_ros.controllers.reversing.controller import reverse

    return envelope.run_holds(reverse(envelope.start_scene(train, speed), gains, 100.0, settle=30.0), train.n)


def envelope_lines(rows: list) -> list[str]:
    return ["## The envelope on generated trains", "",
            f"{GENERATED} random trains per number of carts (lengths 2-7 m, each hitch 1.5 m ahead of to 2 m behind "
            "its cart's axle), backed 100 m from 0.5 m off the line with the hitches at +-2 deg, the default weights. "
            "'The check holds': `mta reverse` and `controllers.reversing.design` accept the train at that speed "
            "(controllers/reversing/envelope.py); 'held': the dynamic level's run with the same gain does not fold "
            "and ends the 100 m within 5 cm of the line, its hitches within 2 deg (as the check holds its own loop). "
            "'held_design': the default weights, else the first of controller.LADDER's gentler ones (the steering's "
            "rate weighed) that the check holds and the dynamic level holds from the same start, what `mta reverse` "
            "takes when no weight is given; its trains then run on the dynamic level with the weights it chose.", "",
            *table(rows, HEADER, "rrrrrrrrrr"), ""]


def chart(figures: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for speed, colour in zip(SPEEDS, ("tab:blue", "tab:orange")):
        ax.plot(CARTS, [100 * figures[(n, speed)][1] for n in CARTS], "o-", color=colour,
                label=f"held on the dynamic level, {speed:g} m/s")
        ax.plot(CARTS, [100 * figures[(n, speed)][0] for n in CARTS], "x--", color=colour,
                label=f"accepted by the check, {speed:g} m/s")
        ax.plot(CARTS, [100 * figures[(n, speed)][3] for n in CARTS], "s:", color=colour, alpha=0.6,
                label=f"held with held_design's weights, {speed:g} m/s")
    ax.set_xticks(CARTS)
    ax.set_xlabel("carts (tractor included)")
    ax.set_ylabel(f"% of {GENERATED} generated trains")
    ax.set_ylim(-5, 105)
    ax.set_title("Backing up 100 m with the LQR gain: where it holds")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
