"""summary.md: the figures of one run as a table, or of several side by side with their
differences, then the definitions, the figures and the CSV files."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence


def _fmt(x, spec=".3f", none="-") -> str:
    return none if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _summary_rows(s: dict) -> list[tuple[str, str]]:
    rows = [("scene / train", f"{s['scene']} / {s['train']}"),
            ("duration", f"{s['duration_s']:.2f} s ({s['samples']} poses)"),
            ("distance travelled by A_1", f"{s['distance_A1_m']:.2f} m")]
    if s.get("position_error_m") is not None:
        rows.append(("estimated position error of the run (the bag's metadata)", f"{s['position_error_m']:.2g} m"))
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
