"""Running figures of a run, gathered sample by sample in constant memory."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class RunSummary:
    cart_names: tuple[str, ...]
    samples: int = 0
    t_start: float = math.nan
    t_end: float = math.nan
    distance: float = 0.0  # m, path length of A_1
    traction_energy: float = 0.0  # J, integral of F_A1 V dt
    power_min: float = math.inf
    power_max: float = -math.inf
    max_hitch: list = field(default_factory=list)  # rad, largest |hitch angle| per joint
    min_jackknife_margin: float = math.inf
    stance: object = None  # physics.terrain.Stance of a train on a slope: roll, pitch, rollover margins
    max_roll: float = 0.0  # rad, largest |roll| of any cart
    max_pitch: float = 0.0  # rad, largest |pitch| of any cart
    min_rollover: float = math.inf  # smallest static rollover margin of a cart with track and height
    min_rollover_cart: str = ""
    min_tip: float = math.inf  # the tractor's smallest tip margin (inf: not known)
    min_grip: float = math.inf  # the smallest grip margin of a no-slip axle (inf: not known)
    min_grip_axle: str = ""
    governor: object = None  # run.following.GovernorWatch of the train's traction: whether it held its set speed
    _last: object = None

    def add(self, out) -> None:
        """Take one Outputs sample (trapezoidal integrals between samples)."""
        if self._last is None:
            self.t_start = out.t
            self.max_hitch = [0.0] * len(out.hitch_angle)
        else:
            dt = out.t - self._last.t
            self.distance += 0.5 * dt * (abs(out.speed) + abs(self._last.speed))
            self.traction_energy += 0.5 * dt * (out.power + self._last.power)
        self.samples += 1
        self.t_end = out.t
        self.power_min = min(self.power_min, out.power)
        self.power_max = max(self.power_max, out.power)
        self.max_hitch = [max(m, abs(a)) for m, a in zip(self.max_hitch, out.hitch_angle)]
        self.min_jackknife_margin = min(self.min_jackknife_margin, out.jackknife_margin)
        if self.stance is not None and not self.stance.level:
            self._add_stance(out.heading, out.front[0])
        if self.governor is not None:
            self.governor.add(out)
        self._last = out

    def _add_stance(self, heading, a1) -> None:
        roll, pitch = self.stance.angles(heading, a1)
        self.max_roll = max(self.max_roll, float(np.max(np.abs(roll))))
        self.max_pitch = max(self.max_pitch, float(np.max(np.abs(pitch))))
        margins = self.stance.margins(heading, a1)
        if self.stance.measured.any():
            k = int(np.nanargmin(margins))
            if margins[k] < self.min_rollover:
                self.min_rollover, self.min_rollover_cart = float(margins[k]), self.stance.names[k]

    def _slip_advice(self) -> str:
        relief = self.stance is not None and self.stance.relief is not None
        return "the slip level, which models the drift, takes a plane only" if relief else "run fidelity slip"

    def add_margins(self, margins) -> None:
        """Take the tip and grip margins of one sample (run/margins.Margins; NaN: not known)."""
        if margins.tip < self.min_tip:
            self.min_tip = margins.tip
        if margins.grip < self.min_grip:
            self.min_grip, self.min_grip_axle = margins.grip, margins.grip_axle

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start if self.samples else 0.0

    @property
    def power_mean(self) -> float:
        return self.traction_energy / self.duration if self.duration > 0 else math.nan

    def markdown(self, title: str, extra: dict[str, str] | None = None) -> str:
        rows = [
            ("simulated time", f"{self.duration:.2f} s ({self.samples} samples)"),
            ("distance of A_1", f"{self.distance:.1f} m"),
            ("traction power min / mean / max", f"{self.power_min / 1e3:.1f} / {self.power_mean / 1e3:.1f} / "
                                                f"{self.power_max / 1e3:.1f} kW"),
            ("traction energy", f"{self.traction_energy / 3.6e6:.3f} kWh"),
        ]
        for k, m in enumerate(self.max_hitch):
            rows.append((f"largest hitch angle {self.cart_names[k]}-{self.cart_names[k + 1]}", f"{math.degrees(m):.2f} deg"))
        if math.isfinite(self.min_jackknife_margin):
            rows.append(("smallest jackknife margin", f"{math.degrees(self.min_jackknife_margin):.1f} deg"))
        if self.stance is not None and not self.stance.level:
            rows.append(("largest roll / pitch of a cart", f"{math.degrees(self.max_roll):.2f} / "
                                                           f"{math.degrees(self.max_pitch):.2f} deg"))
            rows.append(("smallest static rollover margin",
                         f"{self.min_rollover:.3f} ({self.min_rollover_cart}; 1 level, 0 tipping)"
                         if self.stance.measured.any() else "not computed: no cart gives track_width and com_height"))
        if self.min_tip < math.inf:  # known (-inf: an axle with no load that must hold)
            rows.append(("smallest tip margin of the tractor", f"{self.min_tip:.3f} (1 on the level, 0 the front "
                                                               "wheels lift)"))
        if self.min_grip < math.inf:
            rows.append(("smallest grip margin", f"{self.min_grip:.3f} ({self.min_grip_axle}; 1 no lateral force, 0 "
                         "the tyres slide)" + (f"; below 0 the no-slip model does not hold: {self._slip_advice()}"
                                               if self.min_grip < 0 else "")))
        if self.governor is not None and self.governor.row():
            rows.append(("set speed held", self.governor.row()))
        rows.extend((extra or {}).items())
        lines = [f"# {title}", "", "| quantity | value |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in rows]
        return "\n".join(lines) + "\n"
