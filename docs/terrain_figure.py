"""Draws docs/terrain.png: (left) the default unit's steady traction power straight up and down a
grade, simulated, against its closed form; (right) each cart's static rollover margin along the
hillside unit's pass across a 24 % side slope (config/sweeps/side_slope.yaml's steepest case).
Both from the package's own runs, so the picture and the code cannot disagree.
Run: python docs/terrain_figure.py"""
import dataclasses
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mta_sim_ros.physics import loader
from mta_sim_ros.physics.terrain import Plane, Stance
from mta_sim_ros.run.simulation import run_scene

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"
G = 9.80665


def steady_power(scene, grade: float) -> float:
    """The mean traction power (W) over the last 10 s of a 40 s straight pass up ``grade``."""
    train = dataclasses.replace(scene.train, terrain=Plane(grade, 0.0))
    seen = []
    _, err = run_scene(dataclasses.replace(scene, train=train, duration=40.0), on_output=seen.append)
    assert err is None, err
    return float(np.mean([o.power for o in seen if o.t >= 30.0]))


def closed_form(train, grade: float, speed: float) -> float:
    """V (sum m_k g (f_k cos a + sin a) + draft): the steady pull up a grade a at speed V."""
    a = math.atan(grade)
    f = {r.cart: r.coefficient for r in train.rolling}
    draft = 30000.0  # default.yaml: 2.5 kN/m x 12 m, speed-independent
    return speed * (sum(c.mass * G * (f[c.name] * math.cos(a) + math.sin(a)) for c in train.carts) + draft)


def main() -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110, layout="constrained")
    straight = loader.load_scene(CONFIG / "scenes" / "straight_pass.yaml")
    grades = np.linspace(-0.06, 0.10, 9)
    simulated = [steady_power(straight, g) / 1e3 for g in grades]
    fine = np.linspace(grades[0], grades[-1], 100)
    left.plot(100 * fine, [closed_form(straight.train, g, 3.0) / 1e3 for g in fine], color="0.4", lw=1,
              label="V (sum m g (f cos a + sin a) + draft)")
    left.plot(100 * grades, simulated, "o", color="tab:red", label="simulated, mean of the last 10 s")
    left.axhline(250, color="tab:gray", ls=":", lw=1)
    left.text(100 * grades[0], 253, "the tractor's 250 kW: past ~7 % it slows below 3 m/s", fontsize=8,
              color="tab:gray")
    left.set_xlabel("grade (%, rise per 100 m, straight up)")
    left.set_ylabel("traction power F_A1 V (kW)")
    left.set_title("default unit at 3 m/s: power against grade", fontsize=10)
    left.grid(True, alpha=0.3)
    left.legend(fontsize=8)

    scene = loader.load_scene(CONFIG / "scenes" / "side_slope_pass.yaml")
    hillside = loader.load_train(CONFIG / "trains" / "hillside_unit.yaml")
    train = dataclasses.replace(hillside, terrain=Plane(0.04, 0.24))
    scene = dataclasses.replace(scene, train=train)
    seen = []
    _, err = run_scene(scene, on_output=seen.append)
    assert err is None, err
    t = np.array([o.t for o in seen])
    margins = Stance(train).margins(np.array([o.heading for o in seen]))
    for k, cart in enumerate(train.carts):
        right.plot(t, margins[:, k], lw=1.5, label=f"{cart.name} (t {cart.track_width:g} m, h {cart.com_height:g} m)")
    right.axhline(0.0, color="k", lw=0.8)
    right.set_ylim(-0.05, 1.05)
    right.set_xlabel("time (s): along the contour, a lane change at 15 s")
    right.set_ylabel("static rollover margin (0: uphill wheels lift)")
    right.set_title("hillside unit across 24 % (4 % ahead)", fontsize=10)
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8, loc="lower left")
    fig.savefig(HERE / "terrain.png")


if __name__ == "__main__":
    main()
