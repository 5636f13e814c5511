"""The fidelity levels of the model, and what every level provides (``Level``).

    kinematic  speed prescribed, q' = G V(t); traction and power by inverse dynamics (kinematic.py)
    dynamic    the article's one-degree-of-freedom model with traction and resistance laws (dynamics.py)
    slip       lateral tyre compliance in place of the no-side-slip constraints (slip.py)

A level is a constant model of one train (as MuJoCo keeps mjModel apart from mjData): built once,
never changed. What changes lives beside it: the state y, and the held input (steering command,
speed set-point, steering rate limit) that every method takes. The run (run/simulation.py), the
guards, the outputs and the sweeps read a level only through ``Level``; none asks which class it
is. ``run/fidelity.py`` chooses the level a scene needs.
"""
from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import numpy as np

from .dynamics import Model, PoseLayout
from .outputs import Outputs
from .spec import FIDELITY_LEVELS, Train

LEVELS = FIDELITY_LEVELS


@runtime_checkable
class Level(Protocol):
    """What every fidelity level provides. The state vector of every level starts with the pose
    x_A1, y_A1, th_1..th_n, psi_1 (``layout``, a ``PoseLayout``); what follows is the level's own
    (the dynamic level's V and governor integral, the slip level's velocities)."""

    name: str  # one of LEVELS
    train: Train
    algorithm: int  # the article's algorithm 1 or 2 for the mass and velocity terms
    layout: PoseLayout  # indices into the state; ``layout.size`` its length
    P: np.ndarray  # the train's packed constants (kernel.pack): its laws, its actuator, the guards' geometry
    has_kernel: bool  # whether ``rhs`` is the compiled kernel on ``P`` (then the steppers run it whole)
    P_outputs: np.ndarray  # the packed constants the kernel reports with (kernel levels)
    dynamic: Model  # the dynamic level of the same train (the start state is built there)

    def from_dynamic_state(self, y) -> np.ndarray:
        """This level's state moving as the dynamic level's state y does."""

    def begin_tick(self, y, v_set: float, tick: float) -> np.ndarray:
        """The state a tick starts from with v_set held (the kinematic level's speed ramp; else y)."""

    def output_input(self, y, v_set: float) -> float:
        """What the traction law of ``P_outputs`` reads in place of v_set when reporting."""

    def rhs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None) -> np.ndarray:
        """y' under the held input; ``max_rate`` None: the actuator's own rate limit."""

    def outputs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None,
                compiled: bool = True) -> Outputs:
        """What the simulator reports at state y (``compiled`` = False: the kernel as plain Python)."""

    def kinetic_energy(self, y, command: float = 0.0, v_set: float = 0.0) -> float:
        """T, J."""


def make_level(name: str, train: Train, algorithm: int = 2) -> Level:
    """The level ``name`` (one of LEVELS) of ``train``. On a height grid (``train.relief``) the slip
    level and algorithm 1 are refused: their gravity is a plane's (docs/terrain.md)."""
    if train.relief is not None and (name == "slip" or algorithm == 1):
        what = "fidelity slip" if name == "slip" else "algorithm 1"
        raise ValueError(f"{what} on the height grid of {train.relief.source or 'the scene'} must be the kinematic or "
                         "dynamic level by algorithm 2: the slip level and algorithm 1 take a plane's gravity only")
    if name == "dynamic":
        return Model(train, algorithm=algorithm)
    if name == "kinematic":
        from .kinematic import KinematicModel

        return KinematicModel(train, algorithm=algorithm)
    if name == "slip":
        from .slip import SlipModel

        return SlipModel(train, algorithm=algorithm)
    raise ValueError(f"fidelity: {name!r} must be one of {', '.join(LEVELS)}")


def lifted(train: Train) -> Train:
    """The train with its implement lifted: the implement cart's drafts taken off (the train
    itself when it has no implement or no draft on it). A level of it is the second, constant
    model a run switches to while the implement is lifted (run/simulation.py)."""
    if train.implement is None or not any(d.cart == train.implement.cart for d in train.draft):
        return train
    cart = train.implement.cart
    return dataclasses.replace(train, draft=tuple(d for d in train.draft if d.cart != cart))
