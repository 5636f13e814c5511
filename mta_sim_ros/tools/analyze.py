"""``mta analyze BAG [BAG ...] [-o DIR]``: plots, a summary and CSV files from recorded runs.

Reads bags written by ``mta run`` or by the node (topics may carry a namespace, ``/unit1/hitch_poses``:
each topic is found by the last component of its name). The train comes from the bag's metadata
record ``mta_sim_ros`` (key ``train_yaml``), so a bag is analysed without the files it was run from.

The report folder (default ``reports/<bag stem>/``; ``reports/compare_<a>_<b>/`` for two bags) holds

* ``trajectory.png``: the paths of every hitch/front point A_k (solid) and rear axle B_k (dashed),
  B_k = A_k - l_k e_k, with the carts' outlines at regular intervals. An outline is a rectangle on
  the cart's axis from A_k back to B_k, or to the rear hitch A_{k+1} when that lies behind the axle
  (a_k > 0); it is 2.5 m wide, or as wide as the cart's draft element (an implement's working width);
* ``speeds.png`` (centre-of-mass speed s'_Ck of each cart), ``power.png`` (traction power F_A1 V, kW),
  ``hitch_angles.png`` (th_{k-1} - th_k, deg), ``steering.png`` (command and the angle the steering
  actuator reached, deg), all against the time since the bag's first pose;
* ``summary.md`` and ``summary.json``: the figures of the run (see :func:`summarize`), and for
  several bags a differences section (see :func:`compare`);
* ``csv/<topic>.csv`` (``csv/<bag>/<topic>.csv`` for several bags): every message of every topic,
  one row each, ``time_s`` (the log time, exact decimal) then the fields, floats written with
  ``repr`` so that reading them back gives the bag's values exactly.

Definitions used in the summary:

off-tracking of cart k
    the largest distance from the cart's axle B_k(t) to the nearest point of the polyline traced by
    the tractor's rear axle B_1 from the start up to the same time t (the ground B_1 has passed
    over), signed: > 0 left of B_1's direction of travel there, i.e. inside a left turn. Samples
    whose nearest point is an end of that polyline are left out (B_k has not yet reached the
    ground B_1 started on, or is level with B_1): there the distance measures the train's length,
    not its tracking. In a steady turn it is R_B1 - R_Bk.
steady radii
    when the applied steering angle psi_1 stayed constant (within 1e-6 rad) over the last third of
    the run, a least-squares circle (geometric fit) through each B_k over that third, next to the
    closed form of ``model.steady.steady_circle`` at the mean psi_1 of that third.
energy balance
    traction work W_N = int F_A1 V dt against the change of kinetic energy
    T = sum 1/2 m_k s'_Ck^2 + 1/2 J_k th'_k^2 plus the work of the resistances
    W_R = int sum F_Bk s'_Bk dt. s'_Bk comes from finite differences of the B_k positions projected on
    e_k and th'_k from heading differences (second-order central differences, numpy.gradient), the
    integrals from the trapezoidal rule at the bag's rate; s'_Ck and F_Bk are the bag's values.
    Residual = W_N - W_R - (T_end - T_start), reported relative to |W_N|, and the largest |residual|
    of the balance over [t_start, t] for any t. The model satisfies the balance to round-off, so
    the residual is the check's own discretisation: O(dt^2) from the differences and the trapezoid
    (on a turn at yaw rate w the central difference shortens s'_Bk by (w dt)^2 / 6), plus O(dt)
    wherever a command changes from tick to tick: the logged power is the value at the end of each
    tick under that tick's held command, so a jump of the traction force at a tick boundary (a
    governor's kp times a set-point step) reaches the trapezoid one sample late.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from ..bag import BagError, read_messages, read_metadata
from ..compat import legend_below, trapezoid
from ..node.runlog import RECORD, recorded_scene_name, recorded_train
from ..physics.steady import SteadyStateError, steady_circle
from ..validate import EXIT_INPUT, InputError, output_folder

# The topics the simulator writes, by the last component of their names.
KNOWN = ("hitch_poses", "cart_velocities", "traction_power", "steering_angle", "applied_steering",
         "speed_setpoint", "clock")
CART_WIDTH = 2.5  # m, outline width of a cart without a draft element
STEADY_STEERING_TOL = 1e-6  # rad: the steering counts as constant over the last third within this
FIGURE_DPI = 100
FIGURES = ("trajectory.png", "speeds.png", "power.png", "hitch_angles.png", "steering.png")


class AnalyzeError(ValueError):
    """A bag the analysis cannot use (no train metadata, no poses)."""


# --------------------------------------------------------------------------- reading a bag


@dataclass
class Series:
    """One topic's samples: times (s, absolute log time) and values (rows)."""

    t: np.ndarray
    ns: np.ndarray  # log times, ns (int64)
    values: np.ndarray  # shape (N, ...)


@dataclass
class BagData:
    """What the analysis takes from one bag. Times are absolute log times (s); ``t0`` is the first
    pose's time, the origin of every plot."""

    path: Path
    label: str  # the bag's name in legends and tables (its stem, made unique)
    scene_name: str
    train: Any  # model.spec.Train
    topics: dict[str, str]  # last name component -> full topic name
    messages: dict[str, list[tuple[int, Any]]]  # full topic name -> [(log_time_ns, msg)]
    poses: Series  # A_k (N, n, 2)
    pose_heading: Series  # th_k from the quaternions (N, n)
    com_speed: Series | None = None  # s'_Ck (N, n)
    heading: Series | None = None  # th_k from cart_velocities.position (N, n)
    resistance: Series | None = None  # F_Bk (N, n)
    power: Series | None = None  # W (N,)
    command: Series | None = None  # rad (N,)
    applied: Series | None = None  # rad (N,)
    setpoint: Series | None = None  # m/s (N,)
    notes: list[str] = field(default_factory=list)

    @property
    def cart_names(self) -> list[str]:
        return [c.name for c in self.train.carts]

    @property
    def n(self) -> int:
        return len(self.train.carts)

    @property
    def t0(self) -> float:
        return float(self.poses.t[0])

    @property
    def title(self) -> str:
        return f"{self.scene_name} ({self.path.name})"

    def axles(self) -> np.ndarray:
        """B_k = A_k - l_k e_k, (N, n, 2)."""
        l = np.array([c.length for c in self.train.carts])
        th = self.pose_heading.values
        e = np.stack([np.cos(th), np.sin(th)], axis=-1)
        return self.poses.values - l[None, :, None] * e

    def hitch_angles(self) -> np.ndarray:
        """th_{k-1} - th_k wrapped to (-pi, pi], (N, n-1), rad."""
        th = self.pose_heading.values
        return wrap(th[:, :-1] - th[:, 1:])


def wrap(angle):
    """Angle(s) wrapped to (-pi, pi]."""
    return -np.remainder(-np.asarray(angle) + math.pi, 2 * math.pi) + math.pi


def quaternion_yaw(q) -> float:
    """Yaw of a geometry_msgs/Quaternion (rotation about z): 2 atan2(z, w) wrapped to (-pi, pi]."""
    return float(wrap(2.0 * math.atan2(q.z, q.w)))


def _find_topics(names: Iterable[str]) -> tuple[dict[str, str], list[str]]:
    """Map the last component of each known topic to its full name (first in sorted order)."""
    found: dict[str, str] = {}
    notes = []
    for full in sorted(names):
        last = full.rstrip("/").rsplit("/", 1)[-1]
        if last in KNOWN:
            if last in found:
                notes.append(f"topic {full} ignored: {found[last]} already read as {last}")
            else:
                found[last] = full
    return found, notes


def _train_from_metadata(path: Path) -> tuple[Any, str]:
    """The train (model.spec.Train) and scene name from the bag's ``mta_sim_ros`` metadata: its
    recorded texts, parsed by the loader's rules (runlog.recorded_train); no file it names is
    opened."""
    meta = read_metadata(path).get(RECORD)
    if not meta:
        raise AnalyzeError(f"{path}: no metadata record '{RECORD}': the bag was not written by mta run or the "
                           "mta_sim_ros node")
    return recorded_train(meta, str(path)), recorded_scene_name(meta, str(path))


def _series(rows: list[tuple[int, Any]], value) -> Series | None:
    if not rows:
        return None
    ns = np.array([t for t, _ in rows], dtype=np.int64)
    return Series(ns / 1e9, ns, np.array([value(m) for _, m in rows], dtype=float))


def load_bag(path: str | os.PathLike, label: str | None = None) -> BagData:
    """Read one bag into a :class:`BagData`.

    Raises:
        BagError: the file is not a readable bag.
        AnalyzeError: no train metadata, or no hitch_poses.
        InputError: the recorded train text breaks a rule (SpecError).
    """
    path = Path(path)
    train, scene_name = _train_from_metadata(path)
    messages: dict[str, list[tuple[int, Any]]] = {}
    for topic, t_ns, msg in read_messages(path):
        messages.setdefault(topic, []).append((t_ns, msg))
    topics, notes = _find_topics(messages)
    if "hitch_poses" not in topics:
        raise AnalyzeError(f"{path}: no hitch_poses topic (topics: {', '.join(sorted(messages)) or 'none'})")
    n = len(train.carts)
    get = lambda name: messages.get(topics.get(name, ""), [])  # noqa: E731
    poses = [(t, m) for t, m in get("hitch_poses") if len(m.poses) == n]
    if len(poses) != len(get("hitch_poses")):
        notes.append(f"{len(get('hitch_poses')) - len(poses)} hitch_poses messages without {n} poses ignored")
    if len(poses) < 2:
        raise AnalyzeError(f"{path}: fewer than 2 hitch_poses messages with {n} poses")
    names = [c.name for c in train.carts]

    def by_cart(field_name):
        def value(m):
            vals = dict(zip(m.name, getattr(m, field_name)))
            return [vals.get(name, math.nan) for name in names]
        return value

    vel = [(t, m) for t, m in get("cart_velocities")]
    data = BagData(
        path=path,
        label=label or path.stem,
        scene_name=scene_name,
        train=train,
        topics=topics,
        messages=messages,
        poses=_series(poses, lambda m: [[p.position.x, p.position.y] for p in m.poses]),
        pose_heading=_series(poses, lambda m: [quaternion_yaw(p.orientation) for p in m.poses]),
        com_speed=_series(vel, by_cart("velocity")),
        heading=_series(vel, by_cart("position")),
        resistance=_series([(t, m) for t, m in vel if len(m.effort) == len(m.name)], by_cart("effort")),
        power=_series(get("traction_power"), lambda m: m.data),
        command=_series(get("steering_angle"), lambda m: m.data),
        applied=_series(get("applied_steering"), lambda m: m.data),
        setpoint=_series(get("speed_setpoint"), lambda m: m.data),
        notes=notes,
    )
    return data


# --------------------------------------------------------------------------- figures of a run


def fit_circle(points: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares circle through ``points`` (m, 2): (x_c, y_c, R, rms of the radial residuals).

    An algebraic (Kasa) fit gives the start; scipy's least_squares then minimises the geometric
    residuals |P - centre| - R.
    """
    from scipy.optimize import least_squares

    x, y = points[:, 0], points[:, 1]
    mx, my = x.mean(), y.mean()
    u, v = x - mx, y - my  # centred for conditioning
    A = np.column_stack([u, v, np.ones_like(u)])
    b = u * u + v * v
    (cu, cv, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    xc, yc = cu / 2, cv / 2
    r0 = math.sqrt(max(c + xc * xc + yc * yc, 0.0))

    def residual(p):
        return np.hypot(u - p[0], v - p[1]) - p[2]

    sol = least_squares(residual, [xc, yc, r0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    xc, yc, r = sol.x
    rms = float(np.sqrt(np.mean(residual(sol.x) ** 2)))
    return float(xc + mx), float(yc + my), float(abs(r)), rms


def distance_to_path(points: np.ndarray, path: np.ndarray, upto: np.ndarray | None = None):
    """Distance of each point to the nearest point of the polyline ``path`` (m, 2), exact.

    ``upto[j]`` (optional) limits point j to the path's vertices 0..upto[j] (the ground traced
    up to then). Returns ``(signed_distance, at_end)``: the distance, > 0 left of the path's
    direction at the nearest point, and whether that nearest point is the first or the last
    allowed point of the path (then the point is not beside the path). Uses a k-d tree: the
    nearest point lies on a segment with an end within (nearest allowed vertex distance + half
    the longest segment) of the query.
    """
    from scipy.spatial import cKDTree

    m = len(points)
    keep = np.ones(len(path), bool)
    keep[1:] = np.any(np.diff(path, axis=0) != 0, axis=1)  # repeated points (train standing still)
    index = np.cumsum(keep) - 1  # original vertex -> vertex of the reduced path
    path = path[keep]
    last = np.full(m, len(path) - 1) if upto is None else index[np.asarray(upto)]
    if len(path) < 2:
        return np.hypot(*(points - path[0]).T), np.ones(m, bool)
    seg = np.diff(path, axis=0)
    seg_len2 = np.einsum("ij,ij->i", seg, seg)
    half = 0.5 * math.sqrt(float(seg_len2.max()))
    tree = cKDTree(path)
    # distance to the nearest allowed vertex: k nearest, k growing until one is allowed
    d_allowed = np.full(m, np.inf)
    todo = np.arange(m)
    k = 16
    while len(todo):
        kk = min(k, len(path))
        d, i = tree.query(points[todo], k=kk)
        d, i = d.reshape(len(todo), -1), i.reshape(len(todo), -1)
        ok = i <= last[todo, None]
        found = ok.any(axis=1)
        d_allowed[todo[found]] = np.where(ok, d, np.inf)[found].min(axis=1)
        if kk == len(path):
            break
        todo, k = todo[~found], 8 * k
    candidates = tree.query_ball_point(points, d_allowed + half + 1e-9)
    rows, segs = [], []
    for j, verts in enumerate(candidates):
        s = {v for i in verts for v in (i - 1, i) if 0 <= v < last[j]}
        rows.extend([j] * len(s))
        segs.extend(s)
    rows, segs = np.array(rows, dtype=int), np.array(segs, dtype=int)
    signed = np.hypot(*(points - path[0]).T)  # a single allowed vertex: the distance to it
    at_end = last == 0
    if len(rows):
        rel = points[rows] - path[segs]
        u = np.clip(np.einsum("ij,ij->i", rel, seg[segs]) / seg_len2[segs], 0.0, 1.0)
        off = rel - u[:, None] * seg[segs]
        dist = np.hypot(off[:, 0], off[:, 1])
        order = np.lexsort((dist, rows))  # by point, nearest first
        best = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        j = rows[best]
        cross = seg[segs[best], 0] * off[best, 1] - seg[segs[best], 1] * off[best, 0]
        signed[j] = np.where(cross >= 0, 1.0, -1.0) * dist[best]
        at_end[j] = (((segs[best] == 0) & (u[best] == 0.0))
                     | ((segs[best] == last[j] - 1) & (u[best] == 1.0)))
    return signed, at_end


def off_tracking(data: BagData) -> list[dict]:
    """Off-tracking of each trailer's axle B_k from the tractor's axle path B_1 (module docstring)."""
    B = data.axles()
    upto = np.arange(len(B))  # B_k(t) against the ground B_1 traced up to t
    result = []
    for k in range(1, data.n):
        d, at_end = distance_to_path(B[:, k], B[:, 0], upto)
        valid = ~at_end
        entry = {"cart": data.cart_names[k], "max_abs_m": None, "signed_m": None, "time_s": None,
                 "samples": int(valid.sum())}
        if valid.any():
            i = int(np.flatnonzero(valid)[np.argmax(np.abs(d[valid]))])
            entry.update(max_abs_m=float(abs(d[i])), signed_m=float(d[i]), time_s=float(data.poses.t[i] - data.t0))
        result.append(entry)
    return result


def steady_radii(data: BagData) -> dict:
    """Circle fits of each B_k over the last third of the run against ``steady_circle``.

    Returns ``{"constant": bool, ...}``; with constant nonzero steering also the fitted and closed-form
    radii per cart.
    """
    t = data.poses.t
    start = t[0] + 2.0 * (t[-1] - t[0]) / 3.0
    steer = data.applied or data.command
    if steer is None:
        return {"constant": False, "reason": "no steering topic"}
    sel = steer.t >= start
    values = steer.values[sel]
    if not len(values):
        return {"constant": False, "reason": "no steering sample in the last third"}
    spread = float(values.max() - values.min())
    result = {"constant": spread <= STEADY_STEERING_TOL, "from_s": float(start - data.t0),
              "steering_rad": float(values.mean()), "steering_spread_rad": spread}
    if not result["constant"]:
        result["reason"] = f"the steering varied by {spread:.3g} rad over the last third"
        return result
    psi = result["steering_rad"]
    if abs(psi) < STEADY_STEERING_TOL:
        result["reason"] = "straight (steering 0): no circle"
        return result
    try:
        closed = steady_circle(data.train, psi)
    except SteadyStateError as err:
        closed = None
        result["closed_form_error"] = str(err)
    B = data.axles()[t >= start]
    carts = []
    for k, name in enumerate(data.cart_names):
        xc, yc, r, rms = fit_circle(B[:, k])
        entry = {"cart": name, "fit_R_B_m": r, "centre": [xc, yc], "fit_rms_m": rms}
        if closed is not None:
            entry["closed_R_B_m"] = closed.R_B[k]
            entry["relative_error"] = (r - closed.R_B[k]) / closed.R_B[k]
        carts.append(entry)
    result["carts"] = carts
    return result


def _aligned(data: BagData, *series: Series | None):
    """Indices into each series (and the poses) at the log times they all share."""
    common = data.poses.ns
    for s in series:
        common = np.intersect1d(common, s.ns)
    idx = [np.searchsorted(data.poses.ns, common)]
    idx += [np.searchsorted(s.ns, common) for s in series]
    return common, idx


def energy_balance(data: BagData) -> dict | None:
    """W_N against Delta T + W_R from the bag's samples (module docstring); None if topics are missing."""
    if data.power is None or data.com_speed is None or data.resistance is None:
        return None
    common, (ip, iw, ic, ir) = _aligned(data, data.power, data.com_speed, data.resistance)
    if len(common) < 3:
        return None
    t = common / 1e9
    th = np.unwrap(data.pose_heading.values[ip], axis=0)
    B = data.axles()[ip]
    m = np.array([c.mass for c in data.train.carts])
    J = np.array([c.yaw_inertia for c in data.train.carts])
    th_dot = np.gradient(th, t, axis=0, edge_order=2)
    vB = np.gradient(B, t, axis=0, edge_order=2)
    sB = vB[..., 0] * np.cos(th) + vB[..., 1] * np.sin(th)  # s'_Bk, signed along e_k
    sC = data.com_speed.values[ic]
    T = 0.5 * (m * sC**2).sum(axis=1) + 0.5 * (J * th_dot**2).sum(axis=1)
    P = data.power.values[iw]
    res_power = (data.resistance.values[ir] * sB).sum(axis=1)
    dt = np.diff(t)
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * dt * ((P - res_power)[1:] + (P - res_power)[:-1]))])
    running = cumulative - (T - T[0])  # the residual of the balance over [t_0, t_i]
    W_N = float(trapezoid(P, t))
    W_R = float(trapezoid(res_power, t))
    dT = float(T[-1] - T[0])
    residual = W_N - W_R - dT
    worst = int(np.argmax(np.abs(running)))
    return {"traction_work_J": W_N, "resistance_work_J": W_R, "kinetic_energy_change_J": dT,
            "kinetic_energy_start_J": float(T[0]), "kinetic_energy_end_J": float(T[-1]),
            "residual_J": residual, "relative_residual": residual / abs(W_N) if W_N else math.nan,
            "max_abs_running_residual_J": float(abs(running[worst])),
            "max_abs_running_residual_time_s": float(t[worst] - data.t0),
            "samples": int(len(t))}


def summarize(data: BagData) -> dict:
    """The figures of one run (JSON-ready): duration, distance of A_1, power, energy, hitch angles,
    off-tracking, steady radii and the energy balance."""
    t = data.poses.t
    A1 = data.poses.values[:, 0]
    out: dict[str, Any] = {
        "bag": str(data.path), "scene": data.scene_name, "train": data.train.name, "carts": data.cart_names,
        "topics": data.topics, "samples": int(len(t)),
        "duration_s": float(t[-1] - t[0]),
        "distance_A1_m": float(np.hypot(*np.diff(A1, axis=0).T).sum()),
    }
    if data.power is not None and len(data.power.t) > 1:
        P, tp = data.power.values, data.power.t
        energy = float(trapezoid(P, tp))
        out["power_kW"] = {"min": float(P.min()) / 1e3, "max": float(P.max()) / 1e3,
                           "mean": energy / float(tp[-1] - tp[0]) / 1e3}
        out["traction_energy_kWh"] = energy / 3.6e6
    hitch = data.hitch_angles()
    out["max_abs_hitch_angle_deg"] = {
        f"{a}-{b}": float(np.degrees(np.abs(hitch[:, k]).max()))
        for k, (a, b) in enumerate(zip(data.cart_names, data.cart_names[1:]))}
    out["off_tracking"] = off_tracking(data) if data.n > 1 else []
    out["steady"] = steady_radii(data)
    out["energy_balance"] = energy_balance(data)
    out["notes"] = data.notes
    return out


# --------------------------------------------------------------------------- comparing bags


def _interp(s: Series, t_rel: np.ndarray, t0: float, hold: bool) -> np.ndarray:
    """Values of ``s`` at times ``t_rel`` (relative to ``t0``): linear, or sample-and-hold."""
    ts = s.t - t0
    vals = s.values.reshape(len(ts), -1)
    if len(ts) == len(t_rel) and np.array_equal(ts, t_rel):
        return vals
    if hold:
        i = np.clip(np.searchsorted(ts, t_rel, side="right") - 1, 0, len(ts) - 1)
        return vals[i]
    return np.column_stack([np.interp(t_rel, ts, vals[:, j]) for j in range(vals.shape[1])])


def compare(a: BagData, b: BagData) -> list[dict]:
    """Largest differences b - a per output, after interpolating b onto a's times (relative to each
    bag's first pose) over the interval both cover. Continuous outputs are interpolated linearly,
    commands (held over each tick) sample-and-hold; headings and hitch angles are wrapped.
    Carts are matched by name; joints by the names of both carts.
    """
    rows = []
    ta = a.poses.t - a.t0
    tb_end = b.poses.t[-1] - b.t0
    common = ta[ta <= tb_end + 1e-12]

    def add(output, unit, diff, scale=1.0, at=None):
        at = common if at is None else at
        if diff.size == 0:
            return
        diff = np.abs(diff) * scale
        i = int(np.nanargmax(diff))
        rows.append({"output": output, "unit": unit, "max_abs_diff": float(diff[i]), "time_s": float(at[i])})

    ia = a.poses.t - a.t0 <= tb_end + 1e-12
    for k, name in enumerate(a.cart_names):
        if name not in b.cart_names:
            continue
        j = b.cart_names.index(name)
        pa = a.poses.values[ia, k]
        pb = _interp(Series(b.poses.t, b.poses.ns, b.poses.values[:, j]), common, b.t0, hold=False)
        add(f"A_{k + 1} position ({name})", "m", np.hypot(*(pb - pa).T))
        Ba, Bb = a.axles()[ia, k], b.axles()[:, j]
        add(f"B_{k + 1} position ({name})", "m",
            np.hypot(*(_interp(Series(b.poses.t, b.poses.ns, Bb), common, b.t0, False) - Ba).T))
        hb = _interp(Series(b.poses.t, b.poses.ns, np.unwrap(b.pose_heading.values[:, j])), common, b.t0, False)
        add(f"heading ({name})", "deg", wrap(hb[:, 0] - np.unwrap(a.pose_heading.values[:, k])[ia]), 180 / math.pi)
        for attr, label, unit in (("com_speed", "centre-of-mass speed", "m/s"), ("resistance", "resistance F_B", "N")):
            sa, sb = getattr(a, attr), getattr(b, attr)
            if sa is None or sb is None:
                continue
            sel = sa.t - a.t0 <= tb_end + 1e-12
            at = sa.t[sel] - a.t0
            vb = _interp(Series(sb.t, sb.ns, sb.values[:, j]), at, b.t0, False)[:, 0]
            add(f"{label} ({name})", unit, vb - sa.values[sel, k], at=at)
    ha, hb_all = a.hitch_angles(), b.hitch_angles()
    for k, (p, q) in enumerate(zip(a.cart_names, a.cart_names[1:])):
        if p in b.cart_names and q in b.cart_names and b.cart_names.index(q) == b.cart_names.index(p) + 1:
            j = b.cart_names.index(p)
            hb = _interp(Series(b.poses.t, b.poses.ns, np.unwrap(hb_all[:, j])), common, b.t0, False)[:, 0]
            add(f"hitch angle {p}-{q}", "deg", wrap(hb - np.unwrap(ha[:, k])[ia]), 180 / math.pi)
    for attr, label, unit, scale, hold in (("power", "traction power", "kW", 1e-3, False),
                                           ("command", "steering command", "deg", 180 / math.pi, True),
                                           ("applied", "applied steering", "deg", 180 / math.pi, False),
                                           ("setpoint", "speed set-point", "m/s", 1.0, True)):
        sa, sb = getattr(a, attr), getattr(b, attr)
        if sa is None or sb is None:
            continue
        sel = (sa.t - a.t0 <= tb_end + 1e-12) & (sa.t - a.t0 >= sb.t[0] - b.t0 - 1e-12)
        at = sa.t[sel] - a.t0
        vb = _interp(sb, at, b.t0, hold)[:, 0]
        add(label, unit, vb - sa.values[sel], scale, at=at)
    return rows


# --------------------------------------------------------------------------- CSV


def _num(x) -> str:
    """A cell: floats as repr (round-trips exactly), the rest as str."""
    if isinstance(x, float):
        return repr(x)
    return str(x)


def _time_s(ns: int) -> str:
    """Log time as an exact decimal string of seconds."""
    sign = "-" if ns < 0 else ""
    sec, frac = divmod(abs(int(ns)), 10**9)
    return f"{sign}{sec}.{frac:09d}"


def _flatten(msg, prefix: str = "") -> list[tuple[str, Any]]:
    """(column, value) pairs of a decoded message: nested fields joined with '.', lists indexed."""
    if isinstance(msg, (list, tuple)):
        items = []
        for i, x in enumerate(msg):
            items += _flatten(x, f"{prefix}{i}.")
        return items
    slots = getattr(type(msg), "__slots__", None)
    if slots is not None and not isinstance(msg, (str, bytes)):
        items = []
        for name in slots:
            items += _flatten(getattr(msg, name), f"{prefix}{name}.")
        return items
    if isinstance(msg, (bytes, bytearray)):
        msg = msg.hex()
    return [(prefix.rstrip("."), msg)]


def csv_rows(data: BagData, topic: str) -> tuple[list[str], list[list[Any]]]:
    """Header and rows (values, not yet text) of one topic, as :func:`write_csv` writes them.

    hitch_poses: ``A<k>_<cart>_x_m, _y_m, _heading_rad`` per cart (heading from the quaternion);
    cart_velocities: ``<cart>_com_speed_mps, <cart>_heading_rad, <cart>_resistance_N``;
    traction_power ``power_W``; steering_angle ``steering_command_rad``; applied_steering
    ``applied_steering_rad``; speed_setpoint ``speed_setpoint_mps``; clock ``clock_sec, clock_nanosec``.
    Any other topic: its fields flattened (``markers.0.pose.position.x``), the union of the columns
    of all its messages, blank where a message lacks one. Header stamps are left out of the known
    topics (the log time is the stamp).
    """
    msgs = data.messages[topic]
    last = topic.rstrip("/").rsplit("/", 1)[-1]
    names = data.cart_names
    if data.topics.get(last) == topic:
        if last == "hitch_poses":
            header = [f"A{k + 1}_{name}_{q}" for k, name in enumerate(names) for q in ("x_m", "y_m", "heading_rad")]
            rows = [[t] + [v for p in m.poses for v in (p.position.x, p.position.y, quaternion_yaw(p.orientation))]
                    for t, m in msgs]
            return ["time_s"] + header, rows
        if last == "cart_velocities":
            header = [f"{name}_{q}" for name in names for q in ("com_speed_mps", "heading_rad", "resistance_N")]
            rows = []
            for t, m in msgs:
                by = {nm: (v, p, e) for nm, v, p, e in
                      zip(m.name, m.velocity, m.position, list(m.effort) or [""] * len(m.name))}
                rows.append([t] + [x for name in names for x in by.get(name, ("", "", ""))])
            return ["time_s"] + header, rows
        column = {"traction_power": "power_W", "steering_angle": "steering_command_rad",
                  "applied_steering": "applied_steering_rad", "speed_setpoint": "speed_setpoint_mps"}.get(last)
        if column:
            return ["time_s", column], [[t, m.data] for t, m in msgs]
        if last == "clock":
            return ["time_s", "clock_sec", "clock_nanosec"], [[t, m.clock.sec, m.clock.nanosec] for t, m in msgs]
    flat = [(t, dict(_flatten(m))) for t, m in msgs]
    columns: dict[str, None] = {}
    for _, f in flat:
        columns.update(dict.fromkeys(f))
    return ["time_s", *columns], [[t] + [f.get(c, "") for c in columns] for t, f in flat]


def csv_name(topic: str) -> str:
    """File name of a topic's CSV: the name without the leading '/', '/' -> '__'."""
    return topic.strip("/").replace("/", "__") + ".csv"


def write_csv(data: BagData, folder: str | os.PathLike) -> list[Path]:
    """One CSV per topic of the bag into ``folder``; returns the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for topic in sorted(data.messages):
        header, rows = csv_rows(data, topic)
        path = folder / csv_name(topic)
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            for row in rows:
                w.writerow([_time_s(row[0])] + [_num(x) for x in row[1:]])
        written.append(path)
    return written


def read_csv(path: str | os.PathLike) -> tuple[list[str], list[list[str]]]:
    """Header and rows (as text) of a CSV written by :func:`write_csv`."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


# --------------------------------------------------------------------------- plots

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


def plot_all(datas: Sequence[BagData], folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    return [plot_trajectory(datas, folder / "trajectory.png"), plot_speeds(datas, folder / "speeds.png"),
            plot_power(datas, folder / "power.png"), plot_hitch_angles(datas, folder / "hitch_angles.png"),
            plot_steering(datas, folder / "steering.png")]


# --------------------------------------------------------------------------- summary text


def _fmt(x, spec=".3f", none="-") -> str:
    return none if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _summary_rows(s: dict) -> list[tuple[str, str]]:
    rows = [("scene / train", f"{s['scene']} / {s['train']}"),
            ("duration", f"{s['duration_s']:.2f} s ({s['samples']} poses)"),
            ("distance travelled by A_1", f"{s['distance_A1_m']:.2f} m")]
    if "power_kW" in s:
        p = s["power_kW"]
        rows.append(("traction power min / mean / max", f"{p['min']:.1f} / {p['mean']:.1f} / {p['max']:.1f} kW"))
        rows.append(("traction energy", f"{s['traction_energy_kWh']:.4f} kWh"))
    for joint, deg in s["max_abs_hitch_angle_deg"].items():
        rows.append((f"max abs hitch angle {joint}", f"{deg:.2f} deg"))
    for o in s["off_tracking"]:
        val = ("-" if o["max_abs_m"] is None
               else f"{o['max_abs_m']:.3f} m ({o['signed_m']:+.3f} m at {o['time_s']:.1f} s)")
        rows.append((f"off-tracking of B ({o['cart']}) from the path of B_1", val))
    e = s["energy_balance"]
    if e:
        rows += [("traction work W_N", f"{e['traction_work_J'] / 1e6:.6f} MJ"),
                 ("resistance work W_R", f"{e['resistance_work_J'] / 1e6:.6f} MJ"),
                 ("kinetic energy change", f"{e['kinetic_energy_change_J'] / 1e3:.4f} kJ"),
                 ("energy balance residual (W_N - W_R - dT) / W_N", f"{e['relative_residual']:.3e}"),
                 ("largest residual over [0, t]", f"{e['max_abs_running_residual_J']:.1f} J at "
                                                  f"{e['max_abs_running_residual_time_s']:.1f} s")]
    st = s["steady"]
    if st.get("constant"):
        text = f"constant at {st['steering_rad']:.4f} rad" + (f": {st['reason']}" if st.get("reason") else "")
    else:
        text = st.get("reason", "varies")
    rows.append(("steering over the last third", text))
    return rows


DEFINITIONS = (
    "Off-tracking of cart k: the largest distance from its rear axle B_k(t) to the nearest point of the "
    "polyline traced by the tractor's rear axle B_1 up to the same time t, signed > 0 to the left of B_1's "
    "direction of travel; samples whose nearest point is an end of that path are left out (B_k not yet on "
    "ground B_1 has covered). In a steady turn it is R_B1 - R_Bk.",
    "Energy balance: W_N = int F_A1 V dt (trapezoidal), W_R = int sum F_Bk s'_Bk dt with s'_Bk from central "
    "differences of the B_k positions along e_k, T = sum 1/2 m_k s'_Ck^2 + 1/2 J_k th'_k^2 with th'_k from "
    "heading differences. The model conserves this balance to round-off, so the residual is the check's "
    "discretisation error at the bag's rate: O(dt^2), plus O(dt) where a held command (the speed set-point) "
    "steps between ticks, since the logged power is each tick's end value.",
    "Steady radii: geometric least-squares circle fits of B_k over the last third of the run, against the "
    "closed form (model.steady.steady_circle), when the applied steering was constant over that third.",
    "Times are from the bag's first pose.",
)


def _steady_table(st: dict) -> list[str]:
    if not st.get("carts"):
        return []
    lines = ["", f"### Steady turn (steering {st['steering_rad']:.6f} rad, constant within "
                 f"{st['steering_spread_rad']:.1e} rad from t = {st['from_s']:.1f} s)", "",
             "| cart | fitted R_B (m) | closed-form R_B (m) | relative error | fit rms (m) |", "|---|---|---|---|---|"]
    for c in st["carts"]:
        lines.append(f"| {c['cart']} | {c['fit_R_B_m']:.6f} | {_fmt(c.get('closed_R_B_m'), '.6f')} | "
                     f"{_fmt(c.get('relative_error'), '.2e')} | {c['fit_rms_m']:.2e} |")
    if st.get("closed_form_error"):
        lines.append(f"\nno closed-form circle: {st['closed_form_error']}")
    return lines


def markdown(summaries: Sequence[dict], labels: Sequence[str], differences: dict[str, list[dict]],
             figures: Sequence[Path], csv_files: Sequence[Path], folder: Path) -> str:
    if len(summaries) == 1:
        s = summaries[0]
        lines = [f"# Analysis of {Path(s['bag']).name} (scene {s['scene']})", "", f"bag: `{s['bag']}`", "",
                 "| quantity | value |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in _summary_rows(s)]
        lines += _steady_table(s["steady"])
    else:
        lines = ["# Comparison of " + ", ".join(f"{lab} ({s['scene']})" for lab, s in zip(labels, summaries)), ""]
        lines += [f"- {lab}: `{s['bag']}`" for lab, s in zip(labels, summaries)] + [""]
        table = [dict(_summary_rows(s)) for s in summaries]
        keys = list(dict.fromkeys(k for t in table for k in t))
        lines += ["| quantity | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
        lines += [f"| {k} | " + " | ".join(t.get(k, "-") for t in table) + " |" for k in keys]
        for lab, s in zip(labels, summaries):
            st = _steady_table(s["steady"])
            if st:
                lines += ["", f"## {lab}"] + st
        for name, rows in differences.items():
            lines += ["", f"## Differences: {name}", "",
                      "Largest |difference| after interpolating the second bag onto the first's times "
                      "(from each bag's first pose) over the time both cover.", "",
                      "| output | largest difference | at time (s) |", "|---|---|---|"]
            lines += [f"| {r['output']} | {r['max_abs_diff']:.6g} {r['unit']} | {r['time_s']:.2f} |" for r in rows]
    lines += ["", "## Definitions", ""] + [f"- {d}" for d in DEFINITIONS] + ["", "## Figures", ""]
    lines += [f"![{p.stem}]({p.relative_to(folder)})" for p in figures]
    lines += ["", "## CSV", ""] + [f"- `{p.relative_to(folder)}`" for p in csv_files]
    notes = [n for s in summaries for n in s.get("notes", [])]
    if notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- the command


def default_folder(bags: Sequence[str | os.PathLike]) -> Path:
    stems = [Path(b).stem for b in bags]
    if len(stems) == 1:
        return Path("reports") / stems[0]
    return Path("reports") / ("compare_" + "_".join(stems))


def _labels(bags: Sequence[str | os.PathLike]) -> list[str]:
    labels, seen = [], {}
    for b in bags:
        stem = Path(b).stem
        seen[stem] = seen.get(stem, 0) + 1
        labels.append(stem if seen[stem] == 1 else f"{stem}_{seen[stem]}")
    return labels


def analyze(bags: Sequence[str | os.PathLike], folder: str | os.PathLike | None = None) -> dict:
    """Write the report of one or more bags; returns ``{"folder", "summaries", "differences",
    "figures", "csv"}``. Several bags are overlaid in the figures and compared with the first one.
    """
    if not bags:
        raise AnalyzeError("no bag given")
    folder = output_folder(folder if folder is not None else default_folder(bags), "--output")
    labels = _labels(bags)
    datas = [load_bag(b, lab) for b, lab in zip(bags, labels)]
    summaries = [summarize(d) for d in datas]
    differences = {f"{d.label} - {datas[0].label}": compare(datas[0], d) for d in datas[1:]}
    figures = plot_all(datas, folder)
    csv_files = []
    for d in datas:
        csv_files += write_csv(d, folder / "csv" if len(datas) == 1 else folder / "csv" / d.label)
    report = {"bags": [str(b) for b in bags], "labels": labels,
              "summaries": summaries[0] if len(datas) == 1 else dict(zip(labels, summaries)),
              "differences": differences}
    (folder / "summary.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    (folder / "summary.md").write_text(markdown(summaries, labels, differences, figures, csv_files, folder))
    return {"folder": folder, "summaries": summaries, "differences": differences, "figures": figures,
            "csv": csv_files}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bags", nargs="+", metavar="BAG", help="MCAP bags from mta run or the node")
    p.add_argument("-o", "--output", help="report folder (default: reports/<bag stem>/, "
                                          "reports/compare_<a>_<b>/ for two bags)")


def main(args: argparse.Namespace) -> int:
    try:
        result = analyze(args.bags, args.output)
    except (BagError, AnalyzeError, InputError, OSError) as err:
        print(f"mta analyze: {err}", file=sys.stderr)
        return EXIT_INPUT if isinstance(err, InputError) else 1
    folder = result["folder"]
    print(f"report: {folder}/summary.md ({len(result['figures'])} figures, {len(result['csv'])} CSV files in "
          f"{folder}/csv)")
    return 0
