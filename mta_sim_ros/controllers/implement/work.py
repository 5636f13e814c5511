"""A field worked from start to end: planned (or given a plan), driven closed loop, measured. What
``mta field run`` and a sweep's field scenes both do (no ROS, no files written here)."""
from __future__ import annotations

import dataclasses
import time

from ...field.coverage import FieldMetrics, metrics
from ...field.plan import plan_field
from ...field.types import Plan, PlanOptions
from .design import Settings
from .drive import FieldRun, run_field


@dataclasses.dataclass
class Work:
    """A field worked and measured."""

    plan: Plan
    train: object
    run: FieldRun
    result: FieldMetrics
    timings: dict  # s: plan, design, compile, loop, metrics


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
    result = metrics(run.trace, train)
    timings["metrics"] = time.perf_counter() - t
    return Work(plan, train, run, result, timings)
