"""The reversing controller's envelope on generated trains (``python -m benchmarks reversing``'s last
section): trains of 2 to 5 carts of random lengths, their hitches ahead of and behind their axles
(benchmarks.common.random_train), backed 100 m at -1 and -3 m/s from each of the check's starts
(envelope.start_scene: 0.5 m off the line, the hitches bent 2 deg in each of envelope.patterns). For each, the check's verdict (envelope.unheld: the kinematic
loop with the actuator's limits) and the dynamic level's run with the same gain (controller.reverse:
held as the check holds its loop, envelope.run_holds: not stopped, and after 100 m the last axle
within 5 cm of the line, the hitches within 2 deg). A refusal that the dynamic run
holds would be a refusal without cause; an acceptance that folds, a check that is not sufficient.
Then ``held_design``'s choice (the default weights, else the first of controller.LADDER that the
check and the dynamic level hold from the nominal starts) run on the dynamic level from a start it
was not chosen on."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..common import table

#: generated trains per number of carts, the numbers of carts and the speeds they back at
GENERATED = 12
CARTS, SPEEDS = (2, 3, 4, 5), (-1.0, -3.0)
HEADER = ["carts", "speed, m/s", "trains", "the check holds", "design accepts", "held on the dynamic level",
          "verdicts agree (starts)", "refused: a hitch at its limit", "of those, folded", "refused: does not settle",
          "of those, not held", "accepted, but not held", "held_design holds", "held with its weights from another start"]
#: the held-out start held_design's weights are judged from (its own search ran from the nominal ones)
OTHER_OFFSET, OTHER_HITCH = 0.3, math.radians(1.0)


def generated(per: int = GENERATED, seed: int = 20261207) -> tuple[list, dict]:
    """(table rows, {(carts, speed): (share design accepts, share held, share held_design holds,
    share held with its weights from another start)})."""
    from mta_sim_ros.controllers.reversing import envelope
    from mta_sim_ros.controllers.reversing.controller import design, held_design
    from mta_sim_ros.validate import InputError

    from ..common import random_train

    rows, figures = [], {}
    for n in CARTS:
        rng = np.random.default_rng(seed + n)
        trains = [random_train(n, rng) for _ in range(per)]
        for speed in SPEEDS:
            c = dict.fromkeys(("checked", "accepted", "held", "agree", "limit", "limit_folded", "unsettled", "unsettled_unheld",
                               "accepted_unheld", "laddered", "other"), 0)
            starts = 0
            for train in trains:
                gains = design(train, speed, check=False)
                whys, oks, folded = [], [], False
                for pattern in envelope.patterns(train):  # each start: the check's verdict and the dynamic run's
                    why = envelope.unheld_from(train, gains, pattern)
                    run = dynamic_run(train, speed, gains, pattern=pattern)
                    whys.append(why)
                    oks.append(envelope.run_holds(run, n))
                    folded |= bool(why) and "jackknife" in run.stopped
                    c["agree"] += (not why) == oks[-1]
                    starts += 1
                why, ok = next((w for w in whys if w), ""), all(oks)
                c["checked"] += not why
                accepted = accepts(train, speed)
                c["accepted"] += accepted
                c["held"] += ok
                limit = "reaches" in why or "breaks" in why
                c["limit"] += limit
                c["limit_folded"] += limit and folded
                c["unsettled"] += bool(why) and not limit
                c["unsettled_unheld"] += bool(why) and not limit and not ok
                c["accepted_unheld"] += accepted and not ok
                try:
                    chosen = held_design(train, speed)
                except InputError:
                    continue
                c["laddered"] += 1
                c["other"] += envelope.run_holds(dynamic_run(train, speed, chosen, OTHER_OFFSET, OTHER_HITCH), n)
            cells = {**c, "agree": f"{c['agree']} of {starts}"}
            rows.append((str(n), f"{speed:g}", str(per), *map(str, cells.values())))
            figures[(n, speed)] = (c["accepted"] / per, c["held"] / per, c["laddered"] / per, c["other"] / per)
            print(rows[-1], flush=True)
    return rows, figures


def accepts(train, speed: float) -> bool:
    """Whether controller.design (mta reverse with the default weights) accepts ``train`` at ``speed``."""
    from mta_sim_ros.controllers.reversing.controller import design
    from mta_sim_ros.validate import InputError

    try:
        design(train, speed)
    except InputError:
        return False
    return True


def dynamic_run(train, speed: float, gains, offset: float | None = None, hitch: float | None = None,
                pattern: tuple | None = None):
    """The dynamic level's run with ``gains``, 100 m back, from a start of the check (envelope.start_scene,
    the hitches' signs ``pattern``) or from ``offset`` m with every hitch at ``hitch`` rad."""
    from mta_sim_ros.controllers.reversing import envelope
    from mta_sim_ros.controllers.reversing.controller import reverse

    scene = envelope.start_scene(train, speed, offset=offset, hitch=hitch, pattern=pattern)
    return reverse(scene, gains, 100.0, settle=30.0)


def envelope_lines(rows: list) -> list[str]:
    return ["## The envelope on generated trains", "",
            f"{GENERATED} random trains per number of carts (lengths 2-7 m, each hitch 1.5 m ahead of to 2 m behind "
            "its cart's axle), backed 100 m from each of the check's nominal starts (0.5 m off the line, the hitches "
            "bent 2 deg alternately and all one way, either sign) with the default weights. 'The check holds': the kinematic check holds the train from every start "
            "(controllers/reversing/envelope.py); 'design accepts': `mta reverse` and `controllers.reversing.design` "
            "accept it, refusing only from a start the check fails and the dynamic level's run fails too "
            "(controller.unheld_on_both); 'held': the dynamic level's run with the same "
            "gain does not fold and ends the 100 m within 5 cm of the line, its hitches within 2 deg (as the check "
            "holds its own loop), from every start; 'verdicts agree' counts starts. A refusal is a hitch reaching its limit in the check's loop ('folded': the dynamic "
            "run jackknifed too) or a loop that does not settle by then; 'accepted, but not held': design accepts the train, the "
            "dynamic level folds it from a start the check holds. 'held_design': the default weights, else "
            "the first of controller.LADDER's gentler ones (the steering's rate weighed) that the check holds and "
            "the dynamic level holds from the nominal starts, what `mta reverse` takes when no weight is given; its "
            f"weights are then judged from a start they were not chosen on ({OTHER_OFFSET:g} m off the line, every "
            f"hitch at +{math.degrees(OTHER_HITCH):g} deg).", "", *table(rows, HEADER, "r" * len(HEADER)), ""]


def chart(figures: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for speed, colour in zip(SPEEDS, ("tab:blue", "tab:orange")):
        ax.plot(CARTS, [100 * figures[(n, speed)][1] for n in CARTS], "o-", color=colour,
                label=f"held on the dynamic level, {speed:g} m/s")
        ax.plot(CARTS, [100 * figures[(n, speed)][0] for n in CARTS], "x--", color=colour,
                label=f"accepted by design (the check, confirmed), {speed:g} m/s")
        ax.plot(CARTS, [100 * figures[(n, speed)][3] for n in CARTS], "s:", color=colour, alpha=0.6,
                label=f"held with held_design's weights from another start, {speed:g} m/s")
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
