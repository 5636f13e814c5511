"""A field worked from start to end: planned (or given a plan), driven closed loop, measured. What
``mta field run`` and a sweep's field scenes both do (no ROS, no files written here)."""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ...field.coverage import FieldMetrics, metrics
from ...field.plan import plan_field
from ...field.types import Plan, PlanOptions
from ...integrate.tableau import TABLEAUX
from ...run.accuracy import SAFETY, Accuracy, points_of, richardson
from .design import Settings
from .drive import FieldRun, run_field


@dataclasses.dataclass
class Work:
    """A field worked and measured."""

    plan: Plan
    train: object
    run: FieldRun
    result: FieldMetrics
    timings: dict  # s: plan, design, compile, loop, accuracy, metrics
    accuracy: Accuracy  # the run's estimated position error


def work_field(field, train, options: PlanOptions | None = None, settings: Settings = Settings(),
               plan: Plan | None = None) -> Work:
    """Plan ``field`` for ``train`` with ``options`` (default: the implement's width, every other
    option the default) unless ``plan`` is given, work it closed loop with ``settings``, measure
    it; each step timed."""
    t = time.perf_counter()
    if plan is None:
        plan = plan_field(field, train, options or PlanOptions(width=train.implement.width))
    timings = {"plan": time.perf_counter() - t}
    run = run_field(plan, train, settings)
    timings.update(run.timings)
    t = time.perf_counter()
    stated = accuracy_of(plan, train, settings, run)
    timings["accuracy"] = time.perf_counter() - t
    t = time.perf_counter()
    result = metrics(run.trace, train)
    timings["metrics"] = time.perf_counter() - t
    return Work(plan, train, run, result, timings, stated)


#: m: the position error a field run's figures bear (its coverage's slivers and tracking error are
#: read at the centimetre); its accuracy line says OVER past it
FIELD_TOLERANCE = 0.01


def accuracy_of(plan: Plan, train, settings: Settings, run: FieldRun) -> Accuracy:
    """The run's estimated position error (run/accuracy.py): the same plan driven at half rk4's step,
    the largest distance between the two runs' A_k, B_k and rear hitch over the ticks both ran,
    times the Richardson factor of rk4 and accuracy.SAFETY, against FIELD_TOLERANCE."""
    half = run_field(plan, train, dataclasses.replace(settings, step=run.step / 2.0))
    a, b = run.trace, half.trace
    rows = min(len(a.t), len(b.t))
    d = np.linalg.norm(points_of(train, a.axle[:rows, :, 0], a.axle[:rows, :, 1], a.heading[:rows])
                       - points_of(train, b.axle[:rows, :, 0], b.axle[:rows, :, 1], b.heading[:rows]), axis=2)
    error = SAFETY * richardson(TABLEAUX["rk4"].order) * float(np.max(d)) if rows else math.nan
    return Accuracy(error, FIELD_TOLERANCE, "rk4", run.step, "step halving, order 4")
