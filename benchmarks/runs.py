"""Node-mode runs of a scene and their errors, for the accuracy benchmarks (method, work-precision,
stability, kinks): ``Simulation.advance`` tick by tick, each tick holding the scene's steering
command and speed set-point at its start (the node's zero-order hold), on the dynamic level;
the hitch points A_1 .. A_n and the last cart's rear hitch A_{n+1} at every publish instant; their
distance from a reference run (DOP853 at a tight tolerance, kinks split).

Error definitions (m, rad; p_j(t) the hitch points, t_i the publish instants i = 0 .. N, T = t_N):
    E_pos   = max_i max_j |p_j(t_i) - p_j^ref(t_i)|          largest hitch position error
    E_final = max_j |p_j(T) - p_j^ref(T)|                     at the final time
    E_head  = max_i max_k |wrap(th_k(t_i) - th_k^ref(t_i))|   heading error, wrap to (-pi, pi]
    E_power = max_i |N(t_i) - N^ref(t_i)| / max_i |N^ref(t_i)|   traction power N = F_A1 V, relative
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings

import numpy as np

#: the accuracy benchmarks' scenes: label, file in config/, what it tests
SCENES = (
    ("headland U-turn", "scenes/headland_turn.yaml", "default train, 3 carts, 70 s"),
    ("slalom", "scenes/slalom.yaml", "default train, 45 s"),
    ("tight turn", "scenes/tight_turn.yaml", "psi_1 = 0.35 rad at 1.5 m/s, hitch 72 deg of 80"),
    ("reversing", "scenes/reversing.yaml", "-1 m/s for 10 s"),
    ("stiff actuator", "scenes/stiff_actuator.yaml", "steering time constant 5 ms"),
    ("long train", "scenes/long_train_turn.yaml", "n = 20 carts, 80 deg turn, 30 s"),
)
#: what stops a run: the model's validity guard, a failing solver, arithmetic gone wrong
STOPS = (ArithmeticError, ValueError, RuntimeError)


# -- error metrics (pure) ----------------------------------------------------------------------

def hitch_points(lengths, offsets, x, y, heading) -> np.ndarray:
    """Hitch points A_1 .. A_{n+1} for a batch of states: shape (N, n + 1, 2).

    A_1 = (x, y); A_{k+1} = A_k - (l_k + a_k) e_k with e_k = (cos th_k, sin th_k) (docs/model.md)."""
    heading = np.atleast_2d(heading)
    step = np.asarray(lengths) + np.asarray(offsets)  # l_k + a_k
    x = np.asarray(x, float).reshape(-1, 1)
    y = np.asarray(y, float).reshape(-1, 1)
    px = np.concatenate([x, x + np.cumsum(-step * np.cos(heading), 1)], 1)
    py = np.concatenate([y, y + np.cumsum(-step * np.sin(heading), 1)], 1)
    return np.stack([px, py], axis=2)


def position_error(points, ref) -> float:
    """E_pos: the largest distance of any point from its reference over all instants, m."""
    return float(np.max(np.linalg.norm(np.asarray(points) - np.asarray(ref), axis=-1)))


def final_error(points, ref) -> float:
    """E_final: the largest distance of any point from its reference at the last instant, m."""
    return float(np.max(np.linalg.norm(np.asarray(points)[-1] - np.asarray(ref)[-1], axis=-1)))


def heading_error(heading, ref) -> float:
    """E_head: the largest heading difference, wrapped to (-pi, pi], rad."""
    d = np.asarray(heading) - np.asarray(ref)
    return float(np.max(np.abs(np.angle(np.exp(1j * d)))))


def power_error(power, ref) -> float:
    """E_power: the largest traction power difference over the largest reference power (relative)."""
    ref = np.asarray(ref)
    return float(np.max(np.abs(np.asarray(power) - ref)) / np.max(np.abs(ref)))


# -- simulations -------------------------------------------------------------------------------

def simulation(scene, **options):
    """A Simulation of the dynamic model (docs/model.md's), whatever fidelity level the scene
    would pick; kinks split unless ``split_kinks=False`` is given."""
    from mta_sim_ros.run.simulation import Simulation

    return Simulation(scene, fidelity="dynamic", **options)


def with_tolerances(scene, rtol, atol):
    """The scene with the adaptive methods' tolerances rtol, atol."""
    return dataclasses.replace(scene, integrator=dataclasses.replace(scene.integrator, rtol=rtol, atol=atol))


@dataclasses.dataclass
class Run:
    """A node-mode run: ``states`` at the publish instants (row 0 the start; NaN from a stop on),
    ``cpu`` process seconds of the ticks, ``nfev`` right-hand-side evaluations, ``stop`` why it
    stopped early ('' when it did not), and the Simulation (or stepper) that ran."""

    states: np.ndarray
    cpu: float
    nfev: int
    stop: str
    sim: object


class Case:
    """One scene prepared for node-mode runs at one tick rate (the scene's when None): its model,
    start state, the held inputs of every tick and the geometry of its hitch points."""

    def __init__(self, scene, rate: float | None = None, label: str = ""):
        self.scene, self.label = scene, label or scene.name
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            probe = simulation(scene, method="DOP853", rate=rate)
        self.tick, self.rate = probe.tick, 1.0 / probe.tick
        self.ticks = int(math.floor(scene.duration / self.tick + 1e-9))
        self.model, self.layout = probe.model, probe.model.layout
        self.y0 = probe.y.copy()
        self.held = [probe.scheduled_inputs(i * self.tick) for i in range(self.ticks)]
        self.lengths = [c.length for c in scene.train.carts]
        self.offsets = [c.hitch_offset for c in scene.train.carts]

    def simulation(self, rtol: float | None = None, atol: float | None = None, quiet: bool = True, **options):
        """A Simulation of this case (its tick; rtol, atol replace the scene's); ``quiet`` keeps
        its stability note out of the output (it stays in ``stability_note``)."""
        scene = self.scene if rtol is None else with_tolerances(self.scene, rtol, atol)
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")
            return simulation(scene, rate=self.rate, **options)

    def run(self, sim=None, keep: bool = True, **options) -> Run:
        """Every tick of the case on ``sim`` (anything with advance(command, v_set), y and
        stepper.nfev; by default ``self.simulation(**options)``); ``keep`` = False keeps no states
        (a timing run)."""
        sim = self.simulation(**options) if sim is None else sim
        states = np.full((self.ticks + 1 if keep else 1, len(self.y0)), np.nan)
        states[0] = sim.y
        advance, held, stop = sim.advance, self.held, ""
        c0 = time.process_time()
        try:
            for i in range(self.ticks):
                advance(*held[i])
                if keep:
                    states[i + 1] = sim.y
        except STOPS as err:
            stop = f"t = {(i + 1) * self.tick:.3g} s: {str(err).split(';')[0][:90]}"
        return Run(states, time.process_time() - c0, sim.stepper.nfev, stop, sim)

    def reference(self, tol: float, method: str = "DOP853") -> Run:
        """The reference run: ``method`` at rtol = atol = ``tol``, largest step the tick, kinks split."""
        return self.run(method=method, step=self.tick, rtol=tol, atol=tol, split_kinks=True)

    def points(self, states) -> np.ndarray:
        """Hitch points at every row of ``states``: (rows, n + 1, 2)."""
        L = self.layout
        return hitch_points(self.lengths, self.offsets, states[:, L.x], states[:, L.y], states[:, L.heading])

    def distance(self, run: Run, ref: Run) -> float:
        """E_pos of a run against a reference (inf if it stopped or left the finite numbers)."""
        if run.stop or not np.all(np.isfinite(run.states)):
            return math.inf
        return position_error(self.points(run.states), self.points(ref.states))

    def errors(self, states, ref_states, inputs) -> dict[str, float]:
        """E_pos, E_final, E_head, E_power of ``states`` against ``ref_states``; ``inputs(i)`` the
        (command, v_set) in force at instant i (for the traction power)."""
        if not np.all(np.isfinite(states)):
            return dict(pos=math.inf, final=math.inf, head=math.inf, power=math.inf)
        L = self.layout
        pts, ref = self.points(states), self.points(ref_states)

        def power(Y):
            return [self.model.terms(y, *inputs(i)).traction * y[L.speed] for i, y in enumerate(Y)]

        return dict(pos=position_error(pts, ref), final=final_error(pts, ref),
                    head=heading_error(states[:, L.heading], ref_states[:, L.heading]),
                    power=power_error(power(states), power(ref_states)))

    def held_at(self, i: int) -> tuple[float, float]:
        """The inputs held over the tick that ends at instant i (the first tick's at i = 0)."""
        return self.held[max(0, i - 1)]


def cases(words, rate: float | None = None) -> list[Case]:
    """The accuracy scenes (``SCENES``) whose file contains one of ``words`` (all when empty)."""
    from mta_sim_ros.physics.loader import load_scene

    from .common import REPO

    return [Case(load_scene(REPO / "config" / path), rate, label) for label, path, _ in SCENES
            if not words or any(w in path for w in words)]
