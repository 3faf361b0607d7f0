"""Simulation results: named columns (spec §7), events, solver statistics, CSV and plots."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .io import atomic_path

PER_VANE_COLUMNS = ("s", "sdot", "normal", "slot1", "slot2")


@dataclass
class SimulationResult:
    model: str
    mode: str
    time: np.ndarray
    angle: np.ndarray
    speed: np.ndarray
    torque: np.ndarray
    vanes: dict  # column name -> array (n_vanes, n_samples)
    parameters: dict
    stats: dict = field(default_factory=dict)
    events: list = field(default_factory=list)  # dicts: time, kind, vane, message
    warnings: list = field(default_factory=list)
    termination: str = "completed"
    extra: dict = field(default_factory=dict)  # further per-sample arrays (e.g. step size)

    @property
    def n_vanes(self) -> int:
        return self.vanes["s"].shape[0]

    def per_vane_columns(self):
        cols = list(PER_VANE_COLUMNS)
        if "penetration" in self.vanes:
            cols.append("penetration")
        return cols

    def columns(self) -> dict:
        out = {"time": self.time, "angle": self.angle, "speed": self.speed, "torque": self.torque}
        for i in range(self.n_vanes):
            for c in self.per_vane_columns():
                out[f"{c}_{i}"] = self.vanes[c][i]
        return out

    def __getitem__(self, name):
        return self.columns()[name]

    def to_csv(self, path) -> None:
        cols = self.columns()
        data = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
        with atomic_path(path) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")

    def plot(self, path, name: str | None = None, x: str = "angle") -> None:
        """Figure set (.png/.svg/.pdf): versus rotor angle in degrees, revolutions overlaid
        (x="time": versus time); `name` (the config's) goes into the title."""
        from .plotting import plot_simulation

        plot_simulation(self, path, name=name, x=x)

    def summary(self) -> str:
        tq = self.torque
        lines = [
            f"model {self.model}, {self.mode} drive, {self.n_vanes} vane(s), "
            f"{self.time[-1] - self.time[0]:.4g} s, {len(self.time)} samples ({self.termination})",
            f"torque: mean {tq.mean():.6g} N m, min {tq.min():.6g}, max {tq.max():.6g}",
            f"speed: mean {self.speed.mean():.6g} rad/s",
            f"housing normal force: max {self.vanes['normal'].max():.4g} N, "
            f"min {self.vanes['normal'].min():.4g} N",
        ]
        if self.stats:
            lines.append("solver: " + ", ".join(f"{k} {v:g}" if isinstance(v, (int, float)) else f"{k} {v}"
                                                  for k, v in self.stats.items()))
        for w in self.warnings:
            lines.append(f"warning: {w}")
        return "\n".join(lines)
