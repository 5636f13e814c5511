"""What a node run's bag says about the run: the metadata record at its start (what was run,
enough for ``mta replay --resimulate``) and the closing figures (tick statistics); and that
record read back from a bag, by the rules of the loader and of validate.py. No ROS here."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

from .. import __version__, validate
from ..physics.loader import load_scene_text, load_train_text
from ..physics.spec import FIDELITY_LEVELS, INTEGRATOR_METHODS, Scene, Train
from ..validate import InputError
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
        # the position tolerance (m): with no step given, the step was chosen to meet it on the scene's inputs
        "tolerance_m": repr(scene.integrator.tolerance),
        "right_hand_side": sim.compiled_note,  # compiled kernels or the same as plain Python; same results
        "rate": str(cfg["publish_rate"]),
        "algorithm": "2",
        "fidelity": sim.level,
        "fidelity_reason": sim.choice.reason,
        **terrain_record(scene),
    }
    meta.update({f"param.{k}": str(v) for k, v in cfg.items()})
    return meta


def terrain_record(scene) -> dict[str, str]:
    """On a height grid, its heights as read (``terrain_heights``, CSV text), its origin and spacing:
    a bag replays and analyses without the grid's file (a GeoTIFF's placement is in the file)."""
    relief = scene.train.relief
    if relief is None:
        return {}
    return {"terrain_heights": relief.as_text(), "terrain_origin": f"{relief.origin[0]!r},{relief.origin[1]!r}",
            "terrain_spacing": repr(relief.spacing)}


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


# --------------------------------------------------------------------------- reading it back
# A bag is untrusted input: what it records is parsed by the loader's and validate's rules from
# its own texts; no path it names is ever opened.

RECORD = "mta_sim_ros"


class RecordError(InputError):
    """A bag's record mta_sim_ros holds a value that breaks a rule (one line)."""


def _recorded_name(meta: Mapping[str, str], key: str, default: str) -> str:
    """The file name a record gives under ``key`` (its last component only), for messages."""
    value = meta.get(key)
    return (os.path.basename(value) if isinstance(value, str) else "") or default


def recorded_train(meta: Mapping[str, str], bag: str) -> Train:
    """The train as the run read it, from the record's train_yaml (loader.load_train_text)."""
    text = _recorded_text(meta, "train_yaml", bag)
    return load_train_text(text, f"the recorded train {_recorded_name(meta, 'train_file', 'train.yaml')!r} of {bag}")


def recorded_scene(meta: Mapping[str, str], bag: str) -> Scene:
    """The scene as the run read it, with its train, from the record's texts (no file opened,
    whatever ``train:`` names)."""
    train = recorded_train(meta, bag)
    text = _recorded_text(meta, "scene_yaml", bag)
    source = f"the recorded scene {_recorded_name(meta, 'scene_file', 'scene.yaml')!r} of {bag}"
    recorded = {k: v for k, v in meta.items() if k.startswith("terrain_") and isinstance(v, str)}
    return load_scene_text(text, source, train, recorded)


def recorded_scene_name(meta: Mapping[str, str], bag: str) -> str:
    """The scene's name: its ``name:`` if the recorded scene text is a mapping with a plain one,
    else the stem of the recorded scene file's name, else the bag's stem."""
    try:
        data = validate.parse_yaml(meta.get("scene_yaml") or "", bag)
    except InputError:
        data = None
    name = data.get("name") if isinstance(data, dict) else None
    if isinstance(name, str) and name.strip() and len(name) <= validate.SHOW_WIDTH and name.isprintable():
        return name
    return Path(_recorded_name(meta, "scene_file", Path(bag).name)).stem


def _recorded_text(meta: Mapping[str, str], key: str, bag: str) -> str:
    if key not in meta:
        raise RecordError(validate.fault_message(key, "(missing)", "given: the file as the run read it",
                                                 f"metadata {RECORD}", bag))
    return meta[key]


def recorded_options(meta: Mapping[str, str], bag: str) -> dict:
    """The run's integrator, rate, clock offset, algorithm, fidelity level and kink splitting,
    each checked by the rules a run is started with. Raises RecordError."""
    where = f"metadata {RECORD}"

    def number(key: str, rule: validate.Rule, default: str | None = None) -> float:
        text = meta.get(key, default)
        if text is None:
            validate.fail(key, "(missing)", f"given: a number {rule.text}", where, bag, RecordError)
        try:
            value = float(text)
        except (TypeError, ValueError):
            value = text
        problem = validate.check_number(value, rule)
        if problem:
            validate.fail(key, validate.show(text), problem, where, bag, RecordError)
        return value

    def choice(key: str, choices: tuple, default: str | None = None) -> str:
        value = meta.get(key, default)
        if value not in choices:
            validate.fail(key, validate.show(value) if value is not None else "(missing)",
                          f"one of {', '.join(map(str, choices))}", where, bag, RecordError)
        return value

    rate_key = "param.publish_rate" if "param.publish_rate" in meta else "rate"
    rate = number(rate_key, validate.PUBLISH_RATE)
    return {
        "method": choice("method", INTEGRATOR_METHODS),
        "step": number("step", validate.step_floor(rate)),
        "rate": rate,
        "clock_offset": number("clock_offset", validate.NON_NEGATIVE, "0"),
        "algorithm": int(choice("algorithm", ("1", "2"), "2")),
        "fidelity": choice("fidelity", ("auto",) + FIDELITY_LEVELS, "auto"),
        # bags from before kink splitting (no split_kinks key) were stepped across the kinks
        "split_kinks": choice("split_kinks", ("True", "False"), "False") == "True",
    }
