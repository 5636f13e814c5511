"""A sweep's spec: the base train and scenes, what varies, how it is sampled, what is dropped.

A spec is a YAML file (config/sweeps/hitching.yaml is the worked example)::

    name: hitching                      # names the results (default: the file's stem)
    train: ../trains/default.yaml       # the base train, relative to the spec
    scenes: [../scenes/headland_turn.yaml, ../scenes/straight_pass.yaml]   # or field scenes
                                        # (../fieldwork/irregular.yaml: a field worked whole)
    fidelity: dynamic                   # the level of every run (default dynamic: one level for all
                                        # schemes, so their metrics compare; auto may pick per scheme)
    sample: {method: grid}              # grid | random (count, seed) | saltelli (count, seed: SALib)
    vary:                               # the factors; a scheme is one value of each
      - path: carts[0].hitch_offset     # listed values (block style: [i] cannot stand unquoted in {...})
        values: [0.5, 1.0, 1.5]
      - path: carts[2].length           # a range (grid: steps points, ends included)
        low: 5
        high: 8
        steps: 4
      - path: scene.speed               # scene.<path>: the field in every scene
        values: [2.5, 3.0]
      - order: carts                    # the order of the carts behind the tractor
      - path: train                     # a choice among train files
        choices: [../trains/a.yaml, ../trains/b.yaml]
      - path: forces.draft              # or among any values (implements)
        choices: [[...], [...]]
    constraints:                        # a scheme that breaks one is dropped before it runs
      - {quantity: total_length, max: 20}                          # total_length, total_mass, carts
    bags: [0, 5]                        # runs that also write a bag (run index), default none
    batch: 128                          # runs per task (a task's runs of one shape step together)

A path names a field of the train file's mapping (``carts[2].hitch_offset``, ``forces.draft[0].width``,
``steering_actuator.time_constant``) or, after ``scene.``, of every scene's (``scene.speed``,
``scene.initial.speed``; a field scene's ``scene.plan.angle_deg``, ``scene.plan.turn``,
``scene.drive.work_speed``). The field must be in the base file (a ``scene.`` field in one scene
at least: it is set in the scenes that have it, as a field scene's plan beside manoeuvre scenes); the loader checks each scheme's
values by the train's and scene's own rules, so a range that leaves them is refused here, at its
ends, before anything runs. Sampling: ``grid`` is every combination (a range has ``steps`` points,
ends included); ``random`` draws ``count`` schemes, each factor uniform (a range) or equally likely
(values, choices, orders), from ``seed``; ``saltelli`` is SALib's Saltelli sequence of ``count``
base samples (count (2 D + 2) schemes for D factors, count a power of 2), for Sobol indices.
"""
from __future__ import annotations

import copy
import itertools
import math
import os
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import validate
from ..field.scene import field_scene_from_data, is_field_scene
from ..physics import loader
from ..physics.spec import Scene
from ..validate import InputError, Range, show

METHODS = ("grid", "random", "saltelli")
FIDELITY = ("kinematic", "dynamic", "slip", "auto")
QUANTITIES = ("total_length", "total_mass", "carts")
SPEC_FIELDS = ("name", "train", "scenes", "fidelity", "sample", "vary", "constraints", "bags", "batch")
#: schemes a sweep may have (grid or samples), runs = schemes x scenes: the client holds every
#: scheme (a tuple of its factors' values) and the final files every row, ~200 MB at the bound;
#: 2 million runs are ~3 hours at this 2-core machine's 190 runs per second
MAX_SCHEMES = 2_000_000
MAX_SCENES = 100
MAX_RUNS = 2_000_000
BATCH = Range.of(1, 100_000)
STEPS = Range.of(1, 100_000)
COUNT = Range.of(1, MAX_SCHEMES)
SEED = Range.of(0, 2**32 - 1)

_PATH = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[\d{1,6}\])*(\.[A-Za-z_][A-Za-z0-9_]*(\[\d{1,6}\])*)*$")
_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]")


class SweepSpecError(InputError):
    """A sweep spec breaks a rule: one line naming the field, its value, where, and the rule."""


@dataclass(frozen=True)
class Factor:
    """One thing that varies. ``kind``: number (low..high or values), choice (values as given), order."""

    name: str  # the column of the results: the path, or "order"
    kind: str
    target: str  # "train" or "scene" (or "train_file" for a choice of train files)
    parts: tuple  # the path split into keys and indices
    values: tuple = ()  # listed values / choices / permutations (tuples of cart indices)
    low: float = math.nan
    high: float = math.nan
    steps: int = 0
    labels: tuple = ()  # what a choice shows in the results (a file name, the choice's index)

    @property
    def continuous(self) -> bool:
        return self.kind == "number" and not self.values

    def grid(self) -> list:
        if self.continuous:
            return np.linspace(self.low, self.high, self.steps).tolist() if self.steps > 1 else [self.low]
        return list(range(len(self.values))) if self.kind != "number" else list(self.values)

    def from_unit(self, u: float):
        """The factor's value at u in [0, 1): a range scaled, a list indexed."""
        if self.continuous:
            return self.low + u * (self.high - self.low)
        count = len(self.values)
        index = min(int(u * count), count - 1)
        return self.values[index] if self.kind == "number" else index


@dataclass(frozen=True)
class Constraint:
    quantity: str
    low: float
    high: float

    def broken(self, train) -> str:
        """'' if the train keeps the constraint, else why (said in the results and the report)."""
        value = quantity(train, self.quantity)
        if value < self.low:
            return f"{self.quantity} {value:.6g} < min {self.low:g}"
        if value > self.high:
            return f"{self.quantity} {value:.6g} > max {self.high:g}"
        return ""


def quantity(train, name: str) -> float:
    """A constraint's quantity of a train: total_length (sum of l_k and of the rear hitch offsets a_k
    that reach behind the axle, m), total_mass (kg), carts (n)."""
    if name == "total_length":
        carts = train.carts
        return sum(c.length for c in carts) + sum(max(c.hitch_offset, 0.0) for c in carts[:-1])
    if name == "total_mass":
        return sum(c.mass for c in train.carts)
    return float(train.n)


@dataclass
class Spec:
    """A checked sweep spec, with the base files read (their YAML mappings)."""

    name: str
    source: str
    folder: str
    train_data: dict
    train_source: str
    scenes: list  # (name, data, source) per scene
    fidelity: str
    method: str
    count: int
    seed: int
    factors: list
    constraints: list
    bags: frozenset
    batch: int
    text: str = ""  # the spec file as read (kept with the results: a resumed sweep must be the same)
    train_files: dict = field(default_factory=dict)  # a train-file choice's files: label -> (data, source)

    @property
    def scene_names(self) -> list[str]:
        return [name for name, _, _ in self.scenes]


def load(path: str | os.PathLike) -> Spec:
    """Read and check a sweep spec (module docstring); faults raise SweepSpecError in one line."""
    source = str(path)
    text = validate.read_text(path, SweepSpecError)
    data = validate.parse_mapping(text, source, SweepSpecError)
    top = loader.Section(data, "", source, SPEC_FIELDS)
    folder = os.path.dirname(os.path.abspath(source))
    name = top.text("name", os.path.splitext(os.path.basename(source))[0])
    if len(name) > 100 or not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        top.fail("name", name, "a name of at most 100 ASCII letters (A-Z, a-z), digits, '_', '-' or '.'")
    train_rel = top.text("train")
    train_data, train_source = _read_train(top, "train", train_rel, folder)
    scenes = _scenes(top, folder)
    fidelity = top.choice("fidelity", FIDELITY, "dynamic")
    sample = top.section("sample", ("method", "count", "seed"))
    method = sample.choice("method", METHODS, "grid")
    if method == "grid" and sample.has("count"):
        sample.fail("count", sample.values["count"], "left out for method grid (every combination runs)")
    count = 0 if method == "grid" else int(_whole(sample, "count", COUNT, None))
    if method == "saltelli" and count & (count - 1):
        sample.fail("count", count, "a power of 2 for Saltelli's sequence (SALib)")
    seed_value = sample.number("seed", SEED, 0)
    if seed_value != int(seed_value):
        sample.fail("seed", seed_value, "a whole number")
    seed = int(seed_value)
    spec = Spec(name=name, source=source, folder=folder, train_data=train_data, train_source=train_source,
                scenes=scenes, fidelity=fidelity, method=method, count=count, seed=seed, factors=[],
                constraints=[], bags=frozenset(), batch=1, text=text)
    spec.factors = _factors(top, spec)
    spec.constraints = [_constraint(s) for s in top.sections("constraints", ("quantity", "min", "max"))]
    spec.batch = int(_whole(top, "batch", BATCH, 128))
    schemes = scheme_count(spec)
    if schemes > MAX_SCHEMES or schemes * len(scenes) > MAX_RUNS:
        top.fail("vary", f"{schemes} schemes x {len(scenes)} scenes",
                 f"at most {MAX_SCHEMES} schemes and {MAX_RUNS} runs")
    spec.bags = frozenset(_bags(top, schemes * len(scenes)))
    _check_ends(spec)
    return spec


def _whole(s, key: str, rule: Range, default):
    """A whole number obeying ``rule``; required when ``default`` is None."""
    value = s.number(key, rule) if default is None else s.number(key, rule, default)
    if value != int(value):
        s.fail(key, value, "a whole number")
    return value


def _read_train(s, key: str, relative: Any, folder: str) -> tuple[dict, str]:
    if not isinstance(relative, str) or not relative.strip():
        s.fail(key, relative, "a train file's path, relative to the spec")
    path = os.path.normpath(os.path.join(folder, relative))
    if not os.path.isfile(path):
        s.fail(key, relative, f"a train file, relative to the spec's folder (not found: {path})")
    data = loader.read_yaml_mapping(path)
    loader.train_from_data(copy.deepcopy(data), path)  # the base must be a train that loads
    return data, path


def _scenes(top, folder: str) -> list:
    value = top.values.get("scenes")
    if not isinstance(value, list) or not value or len(value) > MAX_SCENES:
        top.fail("scenes", value if value is not None else "(missing)",
                 f"a list of 1 to {MAX_SCENES} scene files, relative to the spec")
    scenes, names = [], set()
    for i, relative in enumerate(value):
        where = f"scenes[{i}]"
        if not isinstance(relative, str) or not relative.strip():
            validate.fail(where, validate.show(relative), "a scene file's path", "top level", top.source, SweepSpecError)
        path = os.path.normpath(os.path.join(folder, relative))
        if not os.path.isfile(path):
            validate.fail(where, validate.show(relative), f"a scene file, relative to the spec's folder (not found: "
                          f"{path})", "top level", top.source, SweepSpecError)
        data = loader.read_yaml_mapping(path)
        if is_field_scene(data):  # a field and how it is worked (field/scene.py)
            scene = field_scene_from_data(copy.deepcopy(data), path)
        else:
            scene = loader.load_scene(path)  # checked with the train it names
        if scene.name in names:
            validate.fail(where, validate.show(relative), f"a scene of another name (two are named {scene.name!r})",
                          "top level", top.source, SweepSpecError)
        names.add(scene.name)
        scenes.append((scene.name, data, path))
    return scenes


def split_path(path: str) -> tuple:
    return tuple(int(i) if i else key for key, i in _PART.findall(path))


def _factors(top, spec: Spec) -> list:
    factors, names = [], set()
    for s in top.sections("vary", ("path", "values", "low", "high", "steps", "choices", "order"), required=True):
        f = _factor(s, spec)
        if f.name in names:
            s.fail("path", f.name, "varied once (it is already a factor)")
        names.add(f.name)
        factors.append(f)
    order = next((i for i, f in enumerate(factors) if f.kind == "order"), None)
    if order is not None:
        n = len(spec.train_data["carts"])
        for rel, (data, _) in spec.train_files.items():
            if len(data.get("carts", [])) != n:
                validate.fail(f"vary[{order}].order", "carts", f"used with trains of one length: {rel} has "
                              f"{len(data.get('carts', []))} carts, the base train {n}", "top level", spec.source,
                              SweepSpecError)
    return factors


def _factor(s, spec: Spec) -> Factor:
    grid = spec.method == "grid"
    if s.has("order"):
        if set(s.values) != {"order"}:
            s.fail("order", s.values["order"], "given alone (the factor is every order of the carts behind the tractor)")
        s.choice("order", ("carts",))
        n = len(spec.train_data.get("carts", []))
        if not 2 <= n - 1 <= 8:
            s.fail("order", "carts", f"used with 2 to 8 carts behind the tractor (the base train has {n - 1})")
        perms = tuple(itertools.permutations(range(1, n)))
        return Factor("order", "order", "train", ("carts",), values=perms,
                      labels=tuple(",".join(str(spec.train_data["carts"][i].get("name", i)) for i in p) for p in perms))
    path = s.text("path")
    if len(path) > 200 or not _PATH.match(path):
        s.fail("path", path, "a field path such as carts[2].hitch_offset or scene.speed")
    parts = split_path(path)
    if parts[0] == "scene":
        target, parts = "scene", parts[1:]
        if not parts:
            s.fail("path", path, "a field of the scenes after scene.")
        holders = [name for name, data, _ in spec.scenes if _holds(data, parts)]
        if not holders:  # the first scene says what it lacks (a typo, most likely)
            name, data, _ = spec.scenes[0]
            _check_target(s, path, data, parts, f"a scene ({name!r} or another)")
    elif parts == ("train",):
        target = "train_file"
    else:
        target = "train"
        _check_target(s, path, spec.train_data, parts, "the base train")
    if s.has("choices"):
        for key in ("values", "low", "high", "steps"):
            if s.has(key):
                s.fail(key, s.values[key], "left out beside choices")
        choices = s.values["choices"]
        if not isinstance(choices, list) or not choices or len(choices) > 1000:
            s.fail("choices", choices, "a list of 1 to 1000 values")
        if target == "train_file":
            files = {}
            for i, rel in enumerate(choices):
                if not isinstance(rel, str):
                    s.fail_item("choices", i, "a train file's path, relative to the spec")
                files[rel] = _read_train(s, f"choices[{i}]", rel, spec.folder)
            spec.train_files.update(files)
            return Factor(path, "choice", target, parts, values=tuple(choices), labels=tuple(choices))
        return Factor(path, "choice", target, parts, values=tuple(copy.deepcopy(choices)),
                      labels=tuple(str(i) for i in range(len(choices))))
    if target == "train_file":
        s.fail("path", path, "given choices: a list of train files")
    if s.has("values"):
        for key in ("low", "high", "steps"):
            if s.has(key):
                s.fail(key, s.values[key], "left out beside values")
        values = s.numbers("values")
        if not values or len(values) > 100_000:
            s.fail("values", s.values["values"], "a list of 1 to 100000 numbers")
        return Factor(path, "number", target, parts, values=tuple(values))
    low, high = s.number("low"), s.number("high")
    if not high >= low:
        s.fail("high", high, f">= low {low:g}")
    if grid:
        steps = int(_whole(s, "steps", STEPS, None))
        if steps > 1 and high == low:
            s.fail("steps", steps, "1 when low = high")
    else:
        if s.has("steps"):
            s.fail("steps", s.values["steps"], f"left out for method {spec.method} (the range is sampled)")
        steps = 0
    return Factor(path, "number", target, parts, low=low, high=high, steps=steps)


def _holds(data, parts) -> bool:
    """Whether ``data`` has the field ``parts`` names."""
    node = data
    for part in parts:
        if isinstance(part, int) and isinstance(node, list) and part < len(node):
            node = node[part]
        elif isinstance(part, str) and isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return False
    return True


def _check_target(s, path: str, data, parts, what: str) -> None:
    """The path must name a field that is in ``data`` (a number where a number is varied)."""
    node = data
    for part in parts:
        ok = (isinstance(part, int) and isinstance(node, list) and part < len(node)) or (
            isinstance(part, str) and isinstance(node, dict) and part in node)
        if not ok:
            s.fail("path", path, f"a field of {what} (no {part!r} there: {_keys(node)})")
        node = node[part]


def _keys(node) -> str:
    if isinstance(node, dict):
        return "fields " + ", ".join(map(str, node)) if node else "no fields"
    if isinstance(node, list):
        return f"a list of {len(node)}"
    return "a value"


def _constraint(s) -> Constraint:
    q = s.choice("quantity", QUANTITIES)
    low, high = s.number("min", default=-math.inf), s.number("max", default=math.inf)
    if not (s.has("min") or s.has("max")):
        s.fail("quantity", q, "given a min or a max")
    if low > high:
        s.fail("max", high, f">= min {low:g}")
    return Constraint(q, low, high)


def _bags(top, runs: int) -> list[int]:
    value = top.values.get("bags", [])
    if not isinstance(value, list) or len(value) > 1000:
        top.fail("bags", value, "a list of at most 1000 run indices")
    out = []
    for i, run in enumerate(value):
        if not (isinstance(run, int) and not isinstance(run, bool) and 0 <= run < runs):
            top.fail_item("bags", i, f"a run index in [0, {runs - 1}]")
        out.append(run)
    return out


# -- schemes ---------------------------------------------------------------------------------------------

def scheme_count(spec: Spec) -> int:
    if spec.method == "grid":
        return math.prod(len(f.grid()) for f in spec.factors)
    if spec.method == "random":
        return spec.count
    return spec.count * (2 * len(spec.factors) + 2)


def schemes(spec: Spec) -> list[tuple]:
    """Every scheme: one value per factor (a number, or an index into the factor's values)."""
    if spec.method == "grid":
        return list(itertools.product(*(f.grid() for f in spec.factors)))
    if spec.method == "random":
        rng = np.random.default_rng(spec.seed)
        u = rng.random((spec.count, len(spec.factors)))
    else:
        u = saltelli_unit(spec)
    return [tuple(f.from_unit(float(x)) for f, x in zip(spec.factors, row)) for row in u]


def sobol_problem(spec: Spec) -> dict:
    """SALib's problem of a sweep's factors, each on [0, 1) (``Factor.from_unit`` maps it)."""
    return {"num_vars": len(spec.factors), "names": [f.name for f in spec.factors],
            "bounds": [[0.0, 1.0]] * len(spec.factors)}


def saltelli_unit(spec: Spec) -> np.ndarray:
    from SALib.sample import sobol as sobol_sample

    return sobol_sample.sample(sobol_problem(spec), spec.count, calc_second_order=True, seed=spec.seed)


def scheme_data(spec: Spec, scheme: tuple) -> tuple[dict, str, list]:
    """(train mapping, its source, [(scene name, scene mapping, source)]) of one scheme."""
    train, source = spec.train_data, spec.train_source
    for f, value in zip(spec.factors, scheme):
        if f.target == "train_file":
            train, source = spec.train_files[f.values[int(value)]]
    train = copy.deepcopy(train)
    scenes = [(name, copy.deepcopy(data), src) for name, data, src in spec.scenes]
    for f, value in zip(spec.factors, scheme):
        if f.target == "train_file":
            continue
        if f.kind == "order":
            carts = train["carts"]
            train["carts"] = [carts[0]] + [carts[i] for i in f.values[int(value)]]
            continue
        new = copy.deepcopy(f.values[int(value)]) if f.kind == "choice" else value
        for data in [train] if f.target == "train" else [d for _, d, _ in scenes if _holds(d, f.parts)]:
            _set(data, f.parts, new)
    return train, source, scenes


def _set(data, parts, value) -> None:
    node = data
    for part in parts[:-1]:
        node = node[part]
    node[parts[-1]] = value


def scheme_label(spec: Spec, scheme: tuple) -> dict:
    """The factors' columns of a scheme: numbers as they are, choices and orders by their labels."""
    return {f.name: (value if f.kind == "number" else f.labels[int(value)]) for f, value in zip(spec.factors, scheme)}


def _check_ends(spec: Spec) -> None:
    """Each factor at each end of its range (the others at their first value) loads as a train and as
    scenes: a range that leaves a field's rule is refused before anything runs, naming the factor."""
    first = [f.grid()[0] if spec.method == "grid" else f.from_unit(0.0) for f in spec.factors]
    for i, f in enumerate(spec.factors):
        if f.kind == "number":
            ends = [f.low, f.high] if f.continuous else [min(f.values), max(f.values)]
        else:
            ends = f.grid()[:1000]  # each choice or order (a choice list holds at most 1000)
        for value in ends:
            scheme = list(first)
            scheme[i] = value
            try:
                build(spec, tuple(scheme))
            except InputError as err:
                raise SweepSpecError(f"vary[{i}] ({f.name} = {_shown(f, value)}) of {spec.source}: {err}") from None


def _shown(f: Factor, value) -> str:
    """A factor's value as a refusal names it: a number, a choice itself (its label is its index
    unless it is a train file), an order's label."""
    if f.kind == "number":
        return f"{value:g}"
    return show(f.values[int(value)]) if f.kind == "choice" and f.target != "train_file" else f.labels[int(value)]


def build(spec: Spec, scheme: tuple):
    """(train, [scene per spec scene]) of a scheme, checked by the loader (SpecError if refused); a
    field scene is a field.scene.FieldScene, checked by its own loader (FieldError) and with the
    train that works it: an implement, a traction law that follows the drive's speeds and speeds it
    can drive (InputError)."""
    train_data, source, scenes = scheme_data(spec, scheme)
    train = loader.train_from_data(train_data, source)
    built = [field_scene_from_data(data, src) if is_field_scene(data) else loader.scene_from_data(data, src, train)
             for _, data, src in scenes]
    for scene in built:
        if not isinstance(scene, Scene):
            worked_by(scene, train)
    return train, built


def worked_by(scene, train) -> None:
    """Refuse (InputError, one line) ``train`` for the field scene: no implement, a traction law that
    ignores the drive's speeds (spec.require_speed_law), speeds it cannot drive (Settings.speeds)."""
    from ..controllers.implement.design import Settings
    from ..field.turning import implement_of
    from ..physics.spec import require_speed_law

    implement_of(train)
    require_speed_law(train, "a field scene's implement controller")
    Settings(**scene.drive).speeds(train)


def has_field_scenes(spec: Spec) -> bool:
    return any(is_field_scene(data) for _, data, _ in spec.scenes)

