"""``mta analyze BAG [BAG ...] [-o DIR]``: plots, a summary and CSV files from recorded runs.

Reads bags written by ``mta run`` or by the node (topics may carry a namespace, ``/unit1/hitch_poses``:
each topic is found by the last component of its name). The train comes from the bag's metadata
record ``mta_sim_ros`` (key ``train_yaml``), so a bag is analysed without the files it was run from.

The report folder (default ``reports/<bag stem>/``; ``reports/compare_<a>_<b>/`` for two bags) holds

* ``trajectory.png``: the paths of every hitch/front point A_k (solid) and rear axle B_k (dashed),
  B_k = A_k - l_k e_k, with the carts' outlines at regular intervals. An outline is a rectangle on
  the cart's axis from A_k back to B_k, or to the rear hitch A_{k+1} when that lies behind the axle
  (a_k > 0); it is 2.5 m wide, or as wide as the cart's draft element (an implement's working width);
* ``speeds.png`` (centre-of-mass speed s'_Ck of each cart), ``power.png`` (traction power F_A1 V, kW),
  ``hitch_angles.png`` (th_{k-1} - th_k, deg), ``steering.png`` (command and the angle the steering
  actuator reached, deg), all against the time since the bag's first pose;
* ``stance.png``, for a run on a terrain (the recorded scene's): each cart's roll and pitch and,
  for the carts with track_width and com_height, the static rollover margin (docs/terrain.md);
* ``summary.md`` and ``summary.json``: the figures of the run (see :func:`analysis.summarize`), and for
  several bags a differences section (see :func:`analysis.compare`);
* ``csv/<topic>.csv`` (``csv/<bag>/<topic>.csv`` for several bags): every message of every topic,
  one row each, ``time_s`` (the log time, exact decimal) then the fields, floats written with
  ``repr`` so that reading them back gives the bag's values exactly.

Definitions used in the summary:

off-tracking of cart k
    the largest distance from the cart's axle B_k(t) to the nearest point of the polyline traced by
    the tractor's rear axle B_1 from the start up to the same time t (the ground B_1 has passed
    over), signed: > 0 left of B_1's direction of travel there, i.e. inside a left turn. Samples
    whose nearest point is an end of that polyline are left out (B_k has not yet reached the
    ground B_1 started on, or is level with B_1): there the distance measures the train's length,
    not its tracking. In a steady turn it is R_B1 - R_Bk.
steady radii
    when the applied steering angle psi_1 stayed constant (within 1e-6 rad) over the last third of
    the run, a least-squares circle (geometric fit) through each B_k over that third, next to the
    closed form of ``model.steady.steady_circle`` at the mean psi_1 of that third.
energy balance
    traction work W_N = int F_A1 V dt against the change of kinetic energy
    T = sum 1/2 m_k s'_Ck^2 + 1/2 J_k th'_k^2 plus the work of the resistances
    W_R = int sum F_Bk s'_Bk dt. s'_Bk comes from finite differences of the B_k positions projected on
    e_k and th'_k from heading differences (second-order central differences, numpy.gradient), the
    integrals from the trapezoidal rule at the bag's rate; s'_Ck and F_Bk are the bag's values.
    Residual = W_N - W_R - (T_end - T_start), reported relative to |W_N|, and the largest |residual|
    of the balance over [t_start, t] for any t. The model satisfies the balance to round-off, so
    the residual is the check's own discretisation: O(dt^2) from the differences and the trapezoid
    (on a turn at yaw rate w the central difference shortens s'_Bk by (w dt)^2 / 6), plus O(dt)
    wherever a command changes from tick to tick: the logged power is the value at the end of each
    tick under that tick's held command, so a jump of the traction force at a tick boundary (a
    governor's kp times a set-point step) reaches the trapezoid one sample late.
"""
from __future__ import annotations

import argparse
import sys

from ..analysis import AnalyzeError, analyze
from ..bag import BagError
from ..validate import EXIT_INPUT, InputError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bags", nargs="+", metavar="BAG", help="MCAP bags from mta run or the node")
    p.add_argument("-o", "--output", help="report folder (default: reports/<bag stem>/, "
                                          "reports/compare_<a>_<b>/ for two bags)")


def main(args: argparse.Namespace) -> int:
    try:
        result = analyze(args.bags, args.output)
    except (BagError, AnalyzeError, InputError, OSError) as err:
        print(f"mta analyze: {err}", file=sys.stderr)
        return EXIT_INPUT if isinstance(err, InputError) else 1
    folder = result["folder"]
    print(f"report: {folder}/summary.md ({len(result['figures'])} figures, {len(result['csv'])} CSV files in "
          f"{folder}/csv)")
    return 0
