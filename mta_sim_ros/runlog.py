"""What a node run's bag says about the run: the metadata record at its start (what was run,
enough for ``mta replay --resimulate``) and the closing figures (tick statistics). No ROS here."""
from __future__ import annotations

from pathlib import Path

from . import __version__
from .timing import TickStats


def run_metadata(scene, sim, cfg: dict) -> dict[str, str]:
    """The record ``mta_sim_ros``: package, scene and train files as read, the integrator and
    fidelity level that run, and every parameter (``param.<name>``)."""
    meta = {
        "package_version": __version__,
        "scene_file": scene.source,
        "scene_yaml": Path(scene.source).read_text(),
        "train_file": scene.train.source,
        "train_yaml": Path(scene.train.source).read_text(),
        "method": sim.method,
        "step": str(sim.step),
        "stepper_step": str(sim.stepper_step),  # smaller than step when sub-stepping for stability
        "stability_note": sim.stability_note or "",
        "split_kinks": str(sim.split_kinks),  # steps split where the right-hand side has a kink
        "right_hand_side": sim.compiled_note,  # compiled kernels or the same as plain Python; same results
        "rate": str(cfg["publish_rate"]),
        "algorithm": "2",
        "fidelity": sim.level,
        "fidelity_reason": sim.choice.reason,
    }
    meta.update({f"param.{k}": str(v) for k, v in cfg.items()})
    return meta


def tick_figures(stats: TickStats, cpu_stats: TickStats) -> dict[str, str]:
    """Whole-run tick compute statistics (s) and deadline misses, and the tick thread's CPU
    percentiles, as strings (the record ``mta_sim_ros.run``, with the session's own figures)."""
    figures = {f"tick_{k}": repr(v) for k, v in stats.summary().items() if not k.startswith("window")}
    figures.update({f"tick_cpu_{k}": repr(v) for k, v in cpu_stats.summary().items()
                    if k in ("p50", "p99", "p99.9", "max")})
    return figures


def tick_line(stats: TickStats, cpu_stats: TickStats, period: float) -> str:
    """The log line of a finished run's ticks ('' before the first tick)."""
    s = stats.summary()
    if not s["count"]:
        return ""
    return (f"{s['count']} ticks: compute p50 {s['p50'] * 1e3:.3f} ms, p99 {s['p99'] * 1e3:.3f} ms, "
            f"p99.9 {s['p99.9'] * 1e3:.3f} ms, max {s['max'] * 1e3:.3f} ms; "
            f"{s['deadline_misses']} deadline misses (tick period {period * 1e3:.2f} ms); "
            f"thread CPU p99.9 {cpu_stats.percentile(99.9) * 1e3:.3f} ms")
