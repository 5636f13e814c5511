"""Draws docs/hilly_field.png: the hillside unit on the hilly field (config/scenes/hilly_field.yaml,
a height grid): (left) the field's contours and the tractor's path; (right) the traction power with
the grade under the tractor, and each cart's static rollover margin along the run. From the
package's own run, so the picture and the code cannot disagree.
Run: python docs/hilly_field_figure.py"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mta_sim_ros.physics import loader
from mta_sim_ros.physics.terrain import Stance
from mta_sim_ros.run.simulation import run_scene

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config"


def main() -> None:
    scene = loader.load_scene(CONFIG / "scenes" / "hilly_field.yaml")
    train, grid = scene.train, scene.train.relief
    seen = []
    _, err = run_scene(scene, on_output=seen.append)
    assert err is None, err
    t = np.array([o.t for o in seen])
    heading = np.array([o.heading for o in seen])
    a1 = np.array([o.front[0] for o in seen])
    stance = Stance(train)
    margins = stance.margins(heading, (a1[:, 0], a1[:, 1]))
    grade = [100 * (grid.at(*o.axle[0]).dzdx * np.cos(o.heading[0]) + grid.at(*o.axle[0]).dzdy * np.sin(o.heading[0]))
             for o in seen]

    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(16, 4.6), dpi=110, layout="constrained")
    shown = left.contourf(grid.xs, grid.ys, grid.heights, levels=16, cmap="terrain")
    left.contour(grid.xs, grid.ys, grid.heights, levels=16, colors="0.3", linewidths=0.4)
    fig.colorbar(shown, ax=left, label="height (m)")
    for k, style in enumerate(("k-", "k--", "k:")):
        left.plot([o.axle[k][0] for o in seen], [o.axle[k][1] for o in seen], style, lw=1.2,
                  label=f"{train.carts[k].name}'s axle")
    left.set_aspect("equal")
    left.set_xlabel("x (m)")
    left.set_ylabel("y (m)")
    left.set_title("hilly field (26 x 36 nodes, 8 m): the unit's path", fontsize=10)
    left.legend(fontsize=8, loc="lower right")

    middle.plot(t, [o.power / 1e3 for o in seen], color="tab:red", lw=1.3, label="traction power")
    middle.set_ylabel("traction power F_A1 V (kW)")
    middle.set_xlabel("time (s): the headland turn from 30 s")
    middle.grid(True, alpha=0.3)
    slope = middle.twinx()
    slope.plot(t, grade, color="tab:brown", lw=1, ls="--", label="grade under the tractor")
    slope.axhline(0.0, color="tab:brown", lw=0.5)
    slope.set_ylabel("grade under the tractor's axle (%)")
    handles = [a.get_legend_handles_labels() for a in (middle, slope)]
    middle.legend(handles[0][0] + handles[1][0], handles[0][1] + handles[1][1], fontsize=8, loc="lower left")
    middle.set_title("power against the grade it meets", fontsize=10)
    for k, cart in enumerate(train.carts):
        right.plot(t, margins[:, k], lw=1.5, label=f"{cart.name} (t {cart.track_width:g} m, h {cart.com_height:g} m)")
    right.set_ylim(0.0, 1.05)
    right.set_xlabel("time (s)")
    right.set_ylabel("static rollover margin (0: uphill wheels lift)")
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8, loc="lower left")
    right.set_title("rollover margins along the run", fontsize=10)
    fig.savefig(HERE / "hilly_field.png")


if __name__ == "__main__":
    main()
