"""Property-based fuzzing (Hypothesis) of every reader of an input, ROS-free and in process:

- the loaders, on random YAML documents and on random mutations of the shipped train and scene
  files: a valid spec or a one-line SpecError, never anything else, and quickly; an accepted
  scene builds a Simulation (or is refused with an InputError) that ticks or stops by a guard;
- the node's params file reader, on random mutations of config/sim.yaml;
- the sweep spec reader, on random mutations of config/sweeps/*.yaml: a spec or one line; an
  accepted spec's first scheme gives rows with a verdict;
- the node's parameters through the ROS-free path: every declared range (and past it) sampled
  at start (``session.RunSession(cfg, ...)``) and live (``RunSession.set_parameters``): accepted
  and the session still ticks, or refused with a reason; never an exception;
- and, not sampled, every number of the default train and scene at every extreme scale (what a
  random mutation reaches too rarely: a 1e-300 m wheelbase).

Runs are bounded (max_examples, deadline) and use no example database."""
from __future__ import annotations

import copy
import math
import tempfile
import warnings
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context
from test_session import FakeClock, Log

from mta_sim_ros.integrate import IntegrationError
from mta_sim_ros.node.pacing import MAX_TIMER_PERIOD
from mta_sim_ros.node.params import BY_NAME, PARAMS, ConfigError, read_params_file
from mta_sim_ros.node.run_session import RunSession
from mta_sim_ros.physics import loader, spec
from mta_sim_ros.physics.guards import ModelValidityError
from mta_sim_ros.run.simulation import Simulation
from mta_sim_ros.validate import InputError

pytestmark = pytest.mark.slow  # Hypothesis searches

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"
TRAIN_FILES = sorted((CONFIG / "trains").glob("*.yaml"))
SCENE_FILES = sorted((CONFIG / "scenes").glob("*.yaml"))
DEFAULT_TRAIN = loader.load_train(CONFIG / "trains" / "default.yaml")
WORK = Path(tempfile.mkdtemp(prefix="mta_fuzz_"))  # bags and params files (Hypothesis reruns examples)

# derandomized: the same examples every run, so that a run that fails fails again
FUZZ = settings(max_examples=150, deadline=2000, database=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow])
RUNS = settings(max_examples=40, deadline=None, database=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow])

# -- values a hostile file may hold ----------------------------------------------------------

#: a float of any magnitude and sign, 1e-320 to 1e308
magnitudes = st.builds(lambda m, e, sign: sign * m * 10.0 ** e, st.floats(1.0, 9.99), st.integers(-320, 307),
                       st.sampled_from([1.0, -1.0]))
WORDS = ["rk4", "RK45", "governor", "constant", "prescribed_speed", "tractor", "seeder", "sine", "lane_change",
         "headland_turn", "step", "auto", "slip", "..", "/etc/passwd", ""]
scalars = st.one_of(
    magnitudes, st.floats(), st.integers(-10**400, 10**400), st.integers(-5, 5), st.booleans(), st.none(),
    st.sampled_from(WORDS), st.text(max_size=6),
)
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(st.text(max_size=8) | st.sampled_from(loader.SCENE_FIELDS), inner, max_size=3),
                      max_leaves=10)


#: factors a number of a shipped file is scaled by
SCALES = [0.0, -1.0, 0.5, 0.9, 1.1, 2.0, 10.0, 0.1, 1e3, 1e-3, 1e6, 1e-6, 1e300, 1e-300]


def paths(data, at=()):
    """Every path (tuple of keys and indices) into a YAML value, its root excluded."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for key, value in items:
        yield at + (key,)
        yield from paths(value, at + (key,))


@st.composite
def mutated(draw, files: list[Path]) -> str:
    """One of ``files`` as YAML text with 1-3 random leaves replaced, removed or renamed."""
    data = yaml.safe_load(draw(st.sampled_from(files)).read_text())
    for _ in range(draw(st.integers(1, 2))):
        at = draw(st.sampled_from(list(paths(data)) or [()]))
        if not at:
            break
        parent = data
        for key in at[:-1]:
            parent = parent[key]
        old = parent[at[-1]]
        how = draw(st.sampled_from(["scale"] * 5 + ["replace", "remove", "rename"]))
        if how == "scale" and isinstance(old, (int, float)) and not isinstance(old, bool) and abs(old) < 1e300:
            parent[at[-1]] = old * draw(st.sampled_from(SCALES))  # near the shipped value: often still valid
        elif how == "remove":
            del parent[at[-1]]
        elif how == "rename" and isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=8))] = parent.pop(at[-1])
        else:
            parent[at[-1]] = draw(values)
    return yaml.safe_dump(data, allow_unicode=True)


def dumped(value) -> str:
    return yaml.safe_dump(value, allow_unicode=True)


documents = st.one_of(values.map(dumped), st.text(max_size=200))


def seen(what: str) -> None:
    """Count an outcome in Hypothesis' statistics (--hypothesis-show-statistics), when in one."""
    if currently_in_test_context():
        event(what)


def assert_one_line(err: Exception) -> None:
    message = str(err)
    assert message and "\n" not in message and " must be " in message, message


# -- the loaders -----------------------------------------------------------------------------


def load_or_refuse(load, text: str):
    """A spec from ``load(text)``, or None after a one-line SpecError; anything else fails."""
    try:
        loaded = load(text)
    except loader.SpecError as err:
        assert_one_line(err)
        seen("refused")
        return None
    seen("loaded")
    return loaded


@FUZZ
@given(documents)
def test_a_random_yaml_document_is_a_spec_or_one_spec_error(text):
    train = load_or_refuse(lambda t: loader.load_train_text(t, "fuzz.yaml"), text)
    assert train is None or isinstance(train, spec.Train)
    scene = load_or_refuse(lambda t: loader.load_scene_text(t, "fuzz.yaml", DEFAULT_TRAIN), text)
    assert scene is None or isinstance(scene, spec.Scene)


@FUZZ
@given(mutated(TRAIN_FILES))
def test_a_mutated_train_file_is_a_train_or_one_spec_error(text):
    train = load_or_refuse(lambda t: loader.load_train_text(t, "fuzz_train.yaml"), text)
    assert train is None or isinstance(train, spec.Train) and train.n >= 1


@FUZZ
@given(mutated(SCENE_FILES))
def test_a_mutated_scene_file_is_a_scene_or_one_spec_error(text):
    scene = load_or_refuse(lambda t: loader.load_scene_text(t, "fuzz_scene.yaml", DEFAULT_TRAIN), text)
    assert scene is None or isinstance(scene, spec.Scene) and scene.duration > 0


SWEEP_FILES = sorted((CONFIG / "sweeps").glob("*.yaml"))


@st.composite
def mutated_sweep(draw) -> str:
    """A shipped sweep spec mutated as ``mutated`` does, its files named by absolute paths (it is
    read from WORK)."""
    data = yaml.safe_load(draw(mutated(SWEEP_FILES)))
    if isinstance(data, dict):
        here = CONFIG / "sweeps"
        if isinstance(data.get("train"), str):
            data["train"] = str((here / data["train"]).resolve())
        if isinstance(data.get("scenes"), list):
            data["scenes"] = [str((here / s).resolve()) if isinstance(s, str) else s for s in data["scenes"]]
    return yaml.safe_dump(data, allow_unicode=True)


@RUNS
@given(mutated_sweep())
def test_a_mutated_sweep_spec_is_a_spec_or_one_line_and_its_first_scheme_runs(text):
    from mta_sim_ros.sweep import engine
    from mta_sim_ros.sweep import spec as sweep_spec

    path = WORK / "fuzz_sweep.yaml"
    path.write_text(text)
    try:
        loaded = sweep_spec.load(path)
    except InputError as err:
        assert_one_line(err)
        seen("refused")
        return
    seen("loaded")
    if sweep_spec.scheme_count(loaded) > 10_000:
        return
    first = sweep_spec.schemes(loaded)[0]
    rows = engine.run_schemes(loaded, [(0, first)])
    assert len(rows) == len(loaded.scenes)
    assert all(r["verdict"] in ("ok", "stopped", "dropped", "refused") for r in rows)
    for r in rows:
        assert "\n" not in r["reason"]
        seen(f"verdict {r['verdict']}")


def ticks_or_stops(scene: spec.Scene, ticks: int = 5) -> None:
    """An accepted scene builds a Simulation or is refused by a rule (InputError, or a level it
    cannot run: ValueError, one line); the simulation ticks or a guard stops it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a stability cut is said, and allowed
        try:
            sim = Simulation(scene)
        except ValueError as err:  # InputError is one
            assert str(err) and "\n" not in str(err)
            seen("simulation refused")
            return
    for _ in range(ticks):
        try:
            sim.advance(*sim.scheduled_inputs(sim.t))
        except (ModelValidityError, IntegrationError):
            seen("stopped by a guard")
            return
        sim.outputs()
    seen("ticked")


@RUNS
@given(st.one_of(mutated(TRAIN_FILES).map(lambda t: ("train", t)), mutated(SCENE_FILES).map(lambda t: ("scene", t))))
def test_an_accepted_mutation_runs_or_is_refused_by_a_rule(which_text):
    which, text = which_text
    if which == "train":
        train = load_or_refuse(lambda t: loader.load_train_text(t, "fuzz_train.yaml"), text)
        scene_text = (CONFIG / "scenes" / "lane_change.yaml").read_text()
        scene = train and load_or_refuse(lambda t: loader.load_scene_text(t, "lane_change.yaml", train), scene_text)
    else:
        scene = load_or_refuse(lambda t: loader.load_scene_text(t, "fuzz_scene.yaml", DEFAULT_TRAIN), text)
    if scene is not None:
        ticks_or_stops(scene)


# -- the node's params file ------------------------------------------------------------------


@FUZZ
@given(st.one_of(mutated([CONFIG / "sim.yaml"]), documents))
def test_a_mutated_params_file_is_parameters_or_one_config_error(text):
    path = WORK / "params.yaml"
    path.write_text(text)
    try:
        given_values = read_params_file(path)
    except ConfigError as err:
        assert_one_line(err)
        return
    assert set(given_values) <= set(BY_NAME)


# -- the node's parameters, at start and live ------------------------------------------------

SCENES = [str(p) for p in SCENE_FILES]
weird = st.one_of(st.none(), st.text(max_size=8), st.booleans(), st.floats(), st.integers(-10**30, 10**30),
                  st.lists(st.integers(), max_size=2), magnitudes)


def sampled(p) -> st.SearchStrategy:
    """Values for parameter ``p``: across its declared range and choices, just past them, and of
    other types."""
    if p.name == "scene_file":
        return st.one_of(st.sampled_from(SCENES), st.just(str(WORK / "nowhere.yaml")))
    if p.name == "bag_dir":
        return st.just(str(WORK / "bags"))
    if p.choices:
        return st.one_of(st.sampled_from(p.choices), st.sampled_from(p.choices), weird)
    if p.low is not None:
        span = p.high - p.low
        if isinstance(p.default, int) and not isinstance(p.default, bool):
            inside = st.integers(int(p.low) - 2, int(p.high) + 2)
        else:
            inside = st.floats(p.low - 0.01 * span, p.high + 0.01 * span)
        return st.one_of(inside, inside, inside, st.sampled_from([p.low, p.high]), weird)
    return st.one_of(st.just(p.default), st.text(max_size=12), weird)


def parameter(among) -> st.SearchStrategy:
    """(name, value) of one of the parameters ``among``, sampled by ``sampled``."""
    return st.sampled_from(among).flatmap(lambda p: sampled(p).map(lambda v: (p.name, v)))


one_parameter = parameter(PARAMS)
#: a live change: mostly of the parameters that may change while running
live_change = st.one_of(parameter([p for p in PARAMS if p.live]), parameter([p for p in PARAMS if p.live]),
                        one_parameter)
configurations = st.lists(one_parameter, max_size=3).map(
    lambda pairs: {**{p.name: p.default for p in PARAMS}, "bag_dir": str(WORK / "bags"), **dict(pairs)})


def started(cfg: dict, clock: FakeClock) -> RunSession | None:
    """A session of ``cfg``, or None after a one-line ConfigError."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return RunSession(copy.deepcopy(cfg), clock=clock, publish=lambda msgs: None, log=Log(),
                              background=False, compute_clock=clock, cpu_clock=clock)
    except ConfigError as err:
        assert str(err).startswith("parameter ") and "\n" not in str(err), str(err)
        seen("refused at start")
        return None


def tick(session: RunSession, clock: FakeClock, n: int) -> None:
    """n firings of the tick timer, one timer period apart: a period a ROS timer can hold."""
    for _ in range(n):
        assert 0.0 <= session.timer_period <= MAX_TIMER_PERIOD, session.timer_period
        clock.advance(session.timer_period or session.sim.tick)
        session.fire()


@RUNS
@given(configurations, st.lists(live_change, max_size=4))
def test_parameters_at_start_and_live_are_taken_or_refused(cfg, changes):
    clock = FakeClock()
    session = started(cfg, clock)
    if session is None:
        return
    try:
        tick(session, clock, 3)
        for name, value in changes:
            before = dict(session.cfg)
            reason = session.set_parameters({name: value})
            assert isinstance(reason, str) and "\n" not in reason
            seen("refused live" if reason else "taken live")
            if reason:
                assert session.cfg == before, reason  # all or nothing
            tick(session, clock, 2)
        assert math.isfinite(session.now)
        session.publish_diagnostics()
        session.reset()
        tick(session, clock, 1)
    finally:
        session.close()


# -- every number of the default train and scene at every scale ------------------------------


#: the factors of the sweep below: zero, the other sign, far up and down, past float's reach
EXTREMES = [0.0, -1.0, 1e-6, 1e6, 1e-300, 1e300]


def numeric_paths(data) -> list[tuple]:
    """The path of each number in ``data``, the first of each field (carts[2].mass stands for
    carts[1].mass too)."""
    found = {}
    for at in paths(data):
        value = _at(data, at)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            found.setdefault(tuple(k if isinstance(k, str) else 0 for k in at), at)
    return list(found.values())


def _at(data, at: tuple):
    for key in at:
        data = data[key]
    return data


def scaled(data, at: tuple, factor: float):
    """A copy of ``data`` with the number at ``at`` multiplied by ``factor``."""
    out = copy.deepcopy(data)
    parent = _at(out, at[:-1])
    parent[at[-1]] = parent[at[-1]] * factor
    return out


def test_every_number_of_the_default_files_at_every_scale_loads_and_runs_or_is_refused():
    """Not sampled: each number of the default train and of a scene on it, scaled by each of
    EXTREMES: a one-line refusal, or a scene that builds its simulation (or is refused by a
    rule) and ticks or stops by a guard."""
    train_data = yaml.safe_load((CONFIG / "trains" / "default.yaml").read_text())
    scene_text = (CONFIG / "scenes" / "lane_change.yaml").read_text()
    scene_data = yaml.safe_load(scene_text)
    for at in numeric_paths(train_data):
        for factor in EXTREMES:
            train = load_or_refuse(lambda t: loader.load_train_text(t, "scaled.yaml"),
                                   dumped(scaled(train_data, at, factor)))
            scene = train and load_or_refuse(lambda t: loader.load_scene_text(t, "lane_change.yaml", train), scene_text)
            if scene is not None:
                ticks_or_stops(scene, ticks=2)
    for at in numeric_paths(scene_data):
        for factor in EXTREMES:
            scene = load_or_refuse(lambda t: loader.load_scene_text(t, "scaled.yaml", DEFAULT_TRAIN),
                                   dumped(scaled(scene_data, at, factor)))
            if scene is not None:
                ticks_or_stops(scene, ticks=2)
