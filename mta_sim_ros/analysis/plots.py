"""The figures of one or several recorded runs (PNG): the trajectory with the carts' outlines, and
the speeds, traction power, hitch angles and steering against time (``mta analyze``'s files)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np

from ..compat import legend_below, trapezoid
from .bagdata import BagData

CART_WIDTH = 2.5  # m, outline width of a cart without a draft element
FIGURE_DPI = 100
FIGURES = ("trajectory.png", "speeds.png", "power.png", "hitch_angles.png", "steering.png")
STYLES = ("-", "--", ":", "-.")  # per bag (time plots)
PATH_STYLES = (("-", "--"), ("-.", ":"), ((0, (5, 1)), (0, (1, 3))), ((0, (3, 1, 1, 1)), (0, (1, 1))))


def _color(k: int) -> str:
    return f"C{k % 10}"


def _figure(width_in: float = 8.0, height_in: float = 4.2):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=FIGURE_DPI, layout="constrained")
    return fig, fig.add_subplot()


def _title(datas: Sequence[BagData], what: str) -> str:
    if len(datas) == 1:
        return f"{what}: {datas[0].title}"
    return f"{what}: " + " vs ".join(d.title for d in datas)


def _label(datas: Sequence[BagData], d: BagData, name: str) -> str:
    return name if len(datas) == 1 else f"{d.label}: {name}"


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=FIGURE_DPI)
    return path


def _outline(A: np.ndarray, th: float, cart, width: float) -> np.ndarray:
    """Corners (5 x 2, closed) of a cart's rectangle: from A_k back to B_k, or to A_{k+1} if behind."""
    e = np.array([math.cos(th), math.sin(th)])
    nrm = np.array([-e[1], e[0]])
    back = A - (cart.length + max(cart.hitch_offset, 0.0)) * e
    w = 0.5 * width
    return np.array([A + w * nrm, back + w * nrm, back - w * nrm, A - w * nrm, A + w * nrm])


def snapshot_interval(duration: float, count: int = 8) -> float:
    """A round interval (1, 2 or 5 times a power of ten, s) giving about ``count`` outlines."""
    if duration <= 0:
        return 1.0
    raw = duration / count
    base = 10.0 ** math.floor(math.log10(raw))
    return next(m * base for m in (1, 2, 5, 10) if m * base >= raw)


def plot_trajectory(datas: Sequence[BagData], path: Path) -> Path:
    from matplotlib.lines import Line2D

    pts = np.concatenate([np.concatenate([d.axles().reshape(-1, 2), d.poses.values.reshape(-1, 2)]) for d in datas])
    margin = 8.0  # m, room for the outlines' half widths
    span = np.maximum(pts.max(axis=0) - pts.min(axis=0) + 2 * margin, 1.0)
    height = float(np.clip(6.4 * span[1] / span[0] + 2.0, 3.6, 8.0))
    fig, ax = _figure(8.0, height)
    step = snapshot_interval(max(d.poses.t[-1] - d.t0 for d in datas))
    for i, d in enumerate(datas):
        sa, sb = PATH_STYLES[i % len(PATH_STYLES)]
        draft_width = {dr.cart: dr.width for dr in d.train.draft}
        A, B = d.poses.values, d.axles()
        for k in range(d.n):
            ax.plot(A[:, k, 0], A[:, k, 1], color=_color(k), ls=sa, lw=1.3)
            ax.plot(B[:, k, 0], B[:, k, 1], color=_color(k), ls=sb, lw=1.0)
        t_rel = d.poses.t - d.t0
        for ts in np.arange(0.0, t_rel[-1] + 1e-9, step):
            j = min(int(np.searchsorted(t_rel, ts - 1e-9)), len(t_rel) - 1)
            for k, cart in enumerate(d.train.carts):
                corners = _outline(A[j, k], d.pose_heading.values[j, k], cart, draft_width.get(cart.name, CART_WIDTH))
                ax.fill(corners[:, 0], corners[:, 1], color=_color(k), alpha=0.10, lw=0)
                ax.plot(corners[:, 0], corners[:, 1], color=_color(k), lw=0.6, alpha=0.7, ls=sa)
            ax.plot(A[j, :, 0], A[j, :, 1], "k.", ms=3)
            ax.annotate(f"{t_rel[j]:.0f} s", A[j, 0], textcoords="offset points", xytext=(4, 4),
                        fontsize=8, color="0.25")
    handles = [Line2D([], [], color=_color(k), lw=4, alpha=0.6, label=name)
               for k, name in enumerate(datas[0].cart_names)]
    for i, d in enumerate(datas):
        sa, sb = PATH_STYLES[i % len(PATH_STYLES)]
        who = "" if len(datas) == 1 else f" ({d.label})"
        handles.append(Line2D([], [], color="k", ls=sa, lw=1.3, label=f"$A_k$ front/hitch{who}"))
        handles.append(Line2D([], [], color="k", ls=sb, lw=1.0, label=f"$B_k$ rear axle{who}"))
    legend_below(fig, ax, handles=handles, fontsize=9, ncol=min(len(handles), 5) if len(datas) == 1 else 3,
                 frameon=False)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)
    ax.set_title(_title(datas, "Trajectory") + f"\ncart outlines every {step:g} s (time since start at $A_1$)",
                 fontsize=10)
    return _save(fig, path)


def _time_plot(datas, path, what, ylabel, curves, extra=None) -> Path:
    """``curves(d)`` yields (t_rel, values, name, color, drawstyle) per curve of one bag;
    ``extra(ax, i, d)`` may draw more per bag."""
    fig, ax = _figure()
    for i, d in enumerate(datas):
        for t, y, name, color, drawstyle in curves(d):
            ax.plot(t, y, color=color, ls=STYLES[i % len(STYLES)] if len(datas) > 1 else "-",
                    lw=1.3, label=_label(datas, d, name), drawstyle=drawstyle)
        if extra is not None:
            extra(ax, i, d)
    ax.set_xlabel("time since start of bag (s)")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.set_title(_title(datas, what), fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if len(handles) > 4:  # below the axes, clear of the curves
        legend_below(fig, ax, handles, labels, fontsize=9, ncol=min(len(datas), 3) if len(datas) > 1 else
                     min(len(handles), 5), frameon=False)
    elif handles:
        ax.legend(fontsize=9, loc="best", framealpha=0.85)
    else:
        ax.text(0.5, 0.5, "nothing to plot in this bag (no such topic, or a single cart)", transform=ax.transAxes,
                ha="center", va="center", color="0.4")
    return _save(fig, path)


def plot_speeds(datas, path) -> Path:
    def curves(d):
        if d.com_speed is not None:
            for k, name in enumerate(d.cart_names):
                yield d.com_speed.t - d.t0, d.com_speed.values[:, k], name, _color(k), "default"
    return _time_plot(datas, path, r"Centre-of-mass speeds $\dot s_{Ck}$", "speed (m/s)", curves)


def plot_power(datas, path) -> Path:
    def curves(d):
        if d.power is not None:
            yield d.power.t - d.t0, d.power.values / 1e3, r"traction power $F_{A1} V$", color(d), "default"

    def color(d):  # one colour per bag
        return ("C3", "C0", "C2", "C4")[next(i for i, x in enumerate(datas) if x is d) % 4]

    def mean_line(ax, i, d):
        if d.power is not None and len(d.power.t) > 1:
            mean = trapezoid(d.power.values, d.power.t) / (d.power.t[-1] - d.power.t[0]) / 1e3
            ax.axhline(mean, color=color(d), alpha=0.7, lw=0.9,
                       ls=STYLES[(i + 2) % len(STYLES)] if len(datas) > 1 else ":",
                       label=_label(datas, d, f"mean {mean:.1f} kW"))
    return _time_plot(datas, path, "Traction power", "power (kW)", curves, extra=mean_line)


def plot_hitch_angles(datas, path) -> Path:
    def curves(d):
        h = np.degrees(d.hitch_angles())
        for k, (a, b) in enumerate(zip(d.cart_names, d.cart_names[1:])):
            yield d.poses.t - d.t0, h[:, k], f"{a} - {b}", _color(k + 1), "default"
    return _time_plot(datas, path, r"Hitch angles $\theta_{k-1} - \theta_k$", "hitch angle (deg)", curves)


def plot_steering(datas, path) -> Path:
    def curves(d):
        if d.command is not None:
            yield d.command.t - d.t0, np.degrees(d.command.values), "command", "C0", "steps-post"
        if d.applied is not None:
            yield d.applied.t - d.t0, np.degrees(d.applied.values), "applied (actuator)", "C1", "default"
    return _time_plot(datas, path, r"Steering angle $\psi_1$", "steering angle (deg, + = left)", curves)


def plot_stance(datas, path) -> Path:
    """Each cart's roll and pitch on the scene's terrain and, for the carts with track_width and
    com_height, the static rollover margin (physics.terrain.Stance), from the poses' headings."""
    from matplotlib.figure import Figure

    from ..physics.terrain import Stance

    fig = Figure(figsize=(8.0, 6.4), dpi=FIGURE_DPI, layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    for i, d in enumerate(datas):
        stance = Stance(d.train)
        t = d.pose_heading.t - d.t0
        a1 = (d.poses.values[:, 0, 0], d.poses.values[:, 0, 1])  # A_1 (a height grid's stance)
        roll, pitch = stance.angles(d.pose_heading.values, a1)
        margins = stance.margins(d.pose_heading.values, a1)
        ls = STYLES[i % len(STYLES)] if len(datas) > 1 else "-"
        for k, name in enumerate(d.cart_names):
            top.plot(t, np.degrees(roll[:, k]), color=_color(k), ls=ls, lw=1.3, label=_label(datas, d, f"{name} roll"))
            top.plot(t, np.degrees(pitch[:, k]), color=_color(k), ls=ls, lw=0.8, alpha=0.6,
                     label=_label(datas, d, f"{name} pitch"))
            if stance.measured[k]:
                bottom.plot(t, margins[:, k], color=_color(k), ls=ls, lw=1.3, label=_label(datas, d, name))
    top.set_ylabel("roll (thick), pitch (thin), deg")
    bottom.set_ylabel("static rollover margin")
    bottom.axhline(0.0, color="0.3", lw=0.8)
    bottom.set_xlabel("time since start of bag (s)")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="best", framealpha=0.85)
    if not bottom.get_legend_handles_labels()[0]:
        bottom.text(0.5, 0.5, "no cart gives track_width and com_height", transform=bottom.transAxes,
                    ha="center", va="center", color="0.4")
    top.set_title(_title(datas, "Roll, pitch and rollover margin on the terrain"), fontsize=10)
    return _save(fig, path)


def grade_met(d: BagData) -> np.ndarray:
    """The grade under the tractor at each pose of a bag, %: 100 tan of its nose-up pitch on the
    scene's terrain (physics.terrain.Stance; at its centre of mass on a height grid)."""
    from ..physics.terrain import Stance

    a1 = (d.poses.values[:, 0, 0], d.poses.values[:, 0, 1])
    return 100.0 * np.tan(-Stance(d.train).angles(d.pose_heading.values, a1)[1][:, 0])


def plot_power_grade(datas, path) -> Path:
    """The traction power against the grade under the tractor, % (100 tan of its nose-up pitch on
    the terrain, physics.terrain.Stance, at the power's times): on a plane or a grid, the power a
    climb costs, as the run met it."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.6), dpi=FIGURE_DPI, layout="constrained")
    ax = fig.subplots()
    for i, d in enumerate(datas):
        if d.power is None:
            continue
        grade = np.interp(d.power.t, d.pose_heading.t, grade_met(d))
        ax.plot(grade, d.power.values / 1e3, ".", ms=2, color=_color(i), label=d.label if len(datas) > 1 else None)
    ax.set_xlabel("grade under the tractor (%, > 0 climbing)")
    ax.set_ylabel(r"traction power $F_{A1} V$ (kW)")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="best")
    ax.set_title(_title(datas, "Traction power against the grade met"), fontsize=10)
    return _save(fig, path)


def figures_of(datas: Sequence[BagData]) -> list[tuple[str, object]]:
    """(file name, plotting function) of every figure of a report on ``datas``: the stance and the
    power against the grade where a run was on sloped ground."""
    sloped = any(d.train.terrain is not None or d.train.relief is not None for d in datas)
    return [("trajectory.png", plot_trajectory), ("speeds.png", plot_speeds), ("power.png", plot_power),
            ("hitch_angles.png", plot_hitch_angles), ("steering.png", plot_steering)] + (
        [("stance.png", plot_stance), ("power_grade.png", plot_power_grade)] if sloped else [])


def plot_all(datas: Sequence[BagData], folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    return [plot(datas, folder / name) for name, plot in figures_of(datas)]
