"""The figures of one recorded run (``mta analyze``): off-tracking, steady radii, the energy balance,
and the summary that holds them. Their definitions: the description of ``mta analyze``
(tools/analyze.py, ``mta analyze --help``).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..compat import trapezoid
from ..physics.steady import SteadyStateError, steady_circle
from .bagdata import BagData, Series
from .track_geometry import distance_to_path, fit_circle

STEADY_STEERING_TOL = 1e-6  # rad: the steering counts as constant over the last third within this


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
        "position_error_m": data.position_error_m,  # as the bag states it; None: it does not
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
