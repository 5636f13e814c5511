"""How accurate a run is: its estimated position error, and the step that meets a tolerance. No ROS.

The error of a run is the largest distance, over its ticks, between a point of the train as run
and the same point of the exact solution under the same held inputs: every hitch point A_k, axle
centre B_k and the last cart's rear hitch (``points``), in metres.

It is estimated from a companion run of the same scene (``companion``):
- a fixed-step method of order p: the same run at half the step (step halving). Where the error
  is C h^p, the run's error is E = D 2^p / (2^p - 1), D the largest distance between the two
  runs' points (Richardson);
- an adaptive method: the same run at a thousandth of its tolerances rtol, atol; its error is then
  far below the run's, and E = D.
The estimate stated is SAFETY x E: the tests hold it at or above the true error (against a DOP853
reference at 1e-12) and at most 10 times above it, on the shipped scenes and on random trains
(test/test_accuracy.py).

A scene without a step asks for a tolerance instead (``integrator.tolerance``, 1e-6 m unless set):
``settle`` then takes the fewest equal steps per tick whose estimate meets it (from one step a tick,
predicting the count from the estimate's order, at most ``ATTEMPTS`` tries).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..integrate.steppers import FIXED_METHODS
from ..integrate.tableau import TABLEAUX
from ..validate import MAX_RUN_STEPS, MAX_STEPS_PER_TICK, InputError, steps_per_tick
from . import whole

#: the estimate stated is this many times the Richardson (or tight-companion) figure
SAFETY = 2.0
#: an adaptive method's companion runs at its tolerances over this
TIGHTER = 1000.0
#: at most this many step counts tried to meet a tolerance
ATTEMPTS = 5


@dataclass(frozen=True)
class Accuracy:
    """What a run states about its accuracy."""

    error: float  # m, the estimated largest position error (``points``) over the run
    tolerance: float | None  # m, what the scene asked for (a field run: FIELD_TOLERANCE; None: none asked)
    method: str
    step: float  # s, the step the run took (the largest, for an adaptive method)
    how: str  # how the estimate was made

    @property
    def meets(self) -> bool:
        """Within the tolerance (or none asked); False where it is over it or not estimated."""
        return self.tolerance is None or self.error <= self.tolerance

    def line(self) -> str:
        if not math.isfinite(self.error):
            return f"position error not estimated ({self.method}, step {self.step:.4g} s; {self.how})"
        verdict = "" if self.tolerance is None else \
            f", {'within' if self.meets else 'OVER'} the tolerance {self.tolerance:g} m"
        return f"estimated position error {self.error:.2g} m{verdict} ({self.method}, step {self.step:.4g} s; {self.how})"

    def metadata(self) -> dict[str, str]:
        """The bag's metadata fields."""
        return {"position_error_m": repr(self.error), "tolerance_m": repr(self.tolerance),
                "error_estimate": self.how}


def richardson(order: int) -> float:
    """The factor from the largest distance between a run and its companion at half the step to the
    run's error, for a method of ``order`` (module docstring)."""
    return 2.0 ** order / (2.0 ** order - 1.0)


def points(train, trace: np.ndarray) -> np.ndarray:
    """(rows, 2n + 1, 2): A_k and B_k of every cart and the last rear hitch, from a run's trace."""
    n = train.n
    cart = trace[:, whole.TRACE_HEAD:].reshape(trace.shape[0], n, whole.TRACE_CART)
    return points_of(train, cart[:, :, whole.TR_BX], cart[:, :, whole.TR_BY], cart[:, :, whole.TR_HEADING])


def points_of(train, bx: np.ndarray, by: np.ndarray, th: np.ndarray) -> np.ndarray:
    """``points`` from the axle centres B_k (bx, by: rows x n) and headings th_k (rows x n)."""
    ex, ey = np.cos(th), np.sin(th)
    length = np.array([c.length for c in train.carts])
    ax, ay = bx + length * ex, by + length * ey
    offset = train.carts[-1].hitch_offset
    rear = np.stack([bx[:, -1] - offset * ex[:, -1], by[:, -1] - offset * ey[:, -1]], axis=1)
    return np.concatenate([np.stack([ax, ay], axis=2), np.stack([bx, by], axis=2), rear[:, None, :]], axis=1)


def distance(train, a: np.ndarray, b: np.ndarray) -> float:
    """The largest distance between the same point (``points``) of two traces, over the rows both ran;
    NaN where no row both ran has finite points (no estimate). Compiled (whole.points_apart)."""
    from .batch import kernel_compiled

    apart = whole.points_apart if kernel_compiled() else whole.points_apart.py_func
    lengths = np.array([c.length for c in train.carts], dtype=np.float64)
    return float(apart(np.ascontiguousarray(a), np.ascontiguousarray(b), min(a.shape[0], b.shape[0]), lengths,
                       float(train.carts[-1].hitch_offset)))


def companion(sim, options: dict) -> tuple[dict, float, str]:
    """(options of the companion run, the factor from the two runs' distance to the run's error,
    how the estimate is made) for a run set up as ``sim``."""
    if sim.method in FIXED_METHODS:
        p = TABLEAUX[sim.method].order
        half = dict(options, method=sim.method, step=sim.stepper_step / 2.0)
        return half, richardson(p), f"step halving, order {p}"
    tight = (sim.rtol / TIGHTER, sim.atol / TIGHTER)
    return dict(options, method=sim.method, tolerances=tight), 1.0, f"rtol, atol / {TIGHTER:g}"


def estimate(scene, run, **options) -> Accuracy:
    """The accuracy of ``run`` = batch.run_trace(scene, **options) (its companion is run here)."""
    return drive(scene, estimating(scene, run, options))


def settle(scene, **options):
    """(the run = batch.run_trace(scene, step=..., **options), its Accuracy). With a step (given
    in ``options`` or by the scene) or an adaptive method: that run and its estimate. Else the
    fewest steps per tick whose estimate meets the scene's tolerance (module docstring); when no
    count of at most validate.MAX_STEPS_PER_TICK does, the finest tried, its estimate saying so."""
    return drive(scene, settling(scene, options))


def drive(scene, search):
    """Run a search (``settling``, ``estimating``) to its answer, each run it asks for run alone
    (batch.run_trace; lanes_batch.settle_many runs many searches' runs across SIMD lanes)."""
    from .batch import run_trace

    request = next(search)
    while True:
        try:
            try:
                run = run_trace(scene, **request)
            except InputError as err:  # the search decides: it gives up on that run, or raises
                request = search.throw(err)
            else:
                request = search.send(run)
        except StopIteration as answer:
            return answer.value


def estimating(scene, run, options: dict):
    """``estimate`` as a search: it yields the options of the one run it needs (the companion) and is
    sent that run (or thrown the InputError its set-up raised); returns the Accuracy."""
    sim, trace = run[0], run[1]
    extra, factor, how = companion(sim, options)
    try:
        other = yield extra
    except InputError as err:  # the companion's half step is past validate.MAX_STEPS_PER_TICK
        return Accuracy(math.nan, scene.integrator.tolerance, sim.method, sim.stepper_step, f"no estimate: {err}")
    error = SAFETY * factor * distance(scene.train, trace[: run[3] + 1], other[1][: other[3] + 1])
    if other[3] < run[3]:  # its guard stopped it first: the estimate covers the run up to there
        how += f"; the companion stopped at t = {other[0].t:.3f} s, the estimate covers the run to there"
    return Accuracy(error, scene.integrator.tolerance, sim.method, sim.stepper_step, how)


def settling(scene, options: dict):
    """``settle`` as a search (``estimating``): yields the options of each run it needs
    (batch.run_trace(scene, **those)), is sent each run; returns (run, Accuracy)."""
    if options.get("step") or scene.integrator.step or run_method(scene, options) not in FIXED_METHODS:
        run = yield options
        return run, (yield from estimating(scene, run, options))
    method = run_method(scene, options)
    tick = 1.0 / (options.get("rate") or scene.publish_rate)
    count, order = 1, TABLEAUX[method].order
    ticks = math.floor(scene.duration / tick + 1e-9)
    # validate's limits with room for the companion's twice the steps: MAX_STEPS_PER_TICK, step_count's
    most = max(1, min(MAX_STEPS_PER_TICK // 2, MAX_RUN_STEPS // max(1, 2 * ticks)))
    run = accuracy = None
    for _ in range(ATTEMPTS):
        try:  # the run at ``count`` steps a tick; refused past validate.MAX_STEPS_PER_TICK (stability)
            trial = yield dict(options, step=tick / count)
        except InputError:
            if run is None:
                yield dict(options, step=tick / count)  # raises, saying why
            break
        stated = yield from estimating(scene, trial, dict(options, step=tick / count))
        if run is not None and not stated.error <= accuracy.error:  # at round-off: more steps do no better
            break
        run, accuracy = trial, stated
        done = steps_per_tick(tick, run[0].stepper_step)  # the stepper may take more (stability)
        if accuracy.meets or done >= most or not math.isfinite(accuracy.error):
            break
        grow = (accuracy.error / accuracy.tolerance) ** (1.0 / order) * 1.2
        count = min(most, max(done + 1, math.ceil(done * grow)))
        if count <= done:  # the run's size allows no more steps
            break
    return run, accuracy


def run_method(scene, options: dict) -> str:
    """The method a run of ``scene`` with ``options`` takes, as Simulation picks it: the option,
    else the slip level's own (an adaptive one) when the run is on the slip level, else the scene's."""
    if options.get("method"):
        return options["method"]
    from ..physics.slip import DEFAULT_METHOD
    from .fidelity import choose

    if choose(scene, forced=options.get("fidelity")).level == "slip":
        return DEFAULT_METHOD
    return scene.integrator.method


#: chosen_step's answers: (scene, options) -> step; a scene is a frozen value, the same one again is
#: the same search (a node's fidelity check, a reset, a controller's set-up)
_CHOSEN: dict = {}


def chosen_step(scene, **options) -> float:
    """The step ``settle`` takes for ``scene`` (s), searched once per scene and options."""
    try:
        key = (scene, tuple(sorted(options.items())))
        hash(key)
    except TypeError:  # an option that is not a value (none today): no memory
        return settle(scene, **options)[0][0].stepper_step
    if key not in _CHOSEN:
        if len(_CHOSEN) > 256:
            _CHOSEN.clear()
        _CHOSEN[key] = settle(scene, **options)[0][0].stepper_step
    return _CHOSEN[key]
