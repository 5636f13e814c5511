"""Draws docs/model.png: the train's points and parameters (MODEL.md), from the package's own
geometry so the picture and the code cannot disagree. Run: python docs/model_figure.py"""
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mta_sim_ros.physics.geometry import cart_points
from mta_sim_ros.physics.loader import load_train

HERE = Path(__file__).resolve().parent
train = load_train(HERE.parent / "config" / "trains" / "default.yaml")
heading = np.array([0.35, 0.12, -0.15])  # a train bending through a turn
psi1 = 0.35
pts = cart_points(train, 0.0, 0.0, heading)

fig, ax = plt.subplots(figsize=(10, 4.6), dpi=110)
colours = ["tab:red", "tab:blue", "tab:green"]
for k, cart in enumerate(train.carts):
    e = np.array([math.cos(heading[k]), math.sin(heading[k])])
    nrm = np.array([-e[1], e[0]])
    A, B, C = pts["A"][k], pts["B"][k], pts["C"][k]
    nxt = pts["A"][k + 1] if k + 1 < train.n else pts["rear_hitch"]
    ax.plot(*np.array([A, nxt]).T, color=colours[k], lw=2.5, solid_capstyle="round")
    half = 1.2  # half track, drawn only
    for side in (-1, 1):  # rear wheels along e_k: no side slip
        w = B + side * half * nrm
        ax.plot(*np.array([w - 0.5 * e, w + 0.5 * e]).T, color="k", lw=4)
    ax.plot(*np.array([B - half * nrm, B + half * nrm]).T, color="k", lw=1)
    ax.plot(*A, "o", color=colours[k], ms=8, mfc="white", mew=2)
    ax.plot(*B, "s", color="k", ms=6)
    ax.plot(*C, "X", color=colours[k], ms=9)
    ax.annotate(f"$A_{k + 1}$", A, textcoords="offset points", xytext=(-4, 10), fontsize=12)
    ax.annotate(f"$B_{k + 1}$", B, textcoords="offset points", xytext=(-6, -20), fontsize=12)
    ax.annotate(f"$C_{k + 1}$", C, textcoords="offset points", xytext=(2, 8), fontsize=12)
    mid = 0.5 * (A + B) + 1.4 * nrm
    ax.annotate(f"$l_{k + 1}$ = {cart.length:g} m", mid, ha="center", fontsize=10, color=colours[k])
    if k + 1 < train.n:
        ax.annotate(f"$a_{k + 1}$ = {cart.hitch_offset:g} m", 0.5 * (B + nxt) - 1.6 * nrm, ha="center", fontsize=10,
                    color=colours[k])
    ax.annotate(cart.name, A - 0.55 * cart.length * e - 3.0 * nrm, ha="center", fontsize=11, style="italic")
# steered front wheels and v_A1 at angle psi_1
e1 = np.array([math.cos(heading[0]), math.sin(heading[0])])
d = np.array([math.cos(heading[0] + psi1), math.sin(heading[0] + psi1)])
A1 = pts["A"][0]
ax.plot(*np.array([A1 - 0.5 * d, A1 + 0.5 * d]).T, color="k", lw=4)
ax.annotate("", A1 + 3.0 * d, A1, arrowprops=dict(arrowstyle="->", lw=1.8))
ax.plot(*np.array([A1, A1 + 3.0 * e1]).T, "k--", lw=0.8)
ax.annotate(r"$v_{A1}$, at $\psi_1$ to $e_1$", A1 + 3.0 * d, textcoords="offset points", xytext=(4, 2), fontsize=11)
ax.annotate(r"$\theta_1$", A1 + 3.2 * e1, fontsize=11)
ax.set_aspect("equal")
ax.set_xlim(-18.5, 5.5)
ax.set_ylim(-5.5, 3.5)
ax.set_xlabel("x, m (forward, REP-103)")
ax.set_ylabel("y, m (left)")
ax.set_title("Default train: tractor, air cart, 12 m seeder. o hitch/front point A, ■ rear axle B, × centre of mass C")
ax.grid(alpha=0.3)
fig.tight_layout()
fig.savefig(HERE / "model.png")
print("wrote", HERE / "model.png")
