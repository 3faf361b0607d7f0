"""Figures in the style of the report (Figures 29-35): angle, s per vane, housing normal force,
slot forces F1/F2, torque; the contact model adds penetration and the integrator step size."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .io import atomic_path  # noqa: E402


def plot_simulation(res, path) -> None:
    panels = [("angle", "rotor angle θ [rad]"), ("s", "vane extension s [mm]"),
              ("normal", "housing normal force N [N]"), ("slots", "slot forces F1, F2 [N]"),
              ("torque", "drive torque τ [N·m]")]
    if "penetration" in res.vanes:
        panels.append(("penetration", "penetration δ [µm]"))
    if "step" in res.extra:
        panels.append(("step", "integrator step [s]"))
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.0 * len(panels)), sharex=True)
    t = res.time
    for ax, (key, label) in zip(axes, panels):
        if key == "angle":
            ax.plot(t, res.angle, "k")
        elif key == "torque":
            ax.plot(t, res.torque, "k")
        elif key == "step":
            ax.semilogy(res.extra["step_time"], res.extra["step"], "k.", ms=2)
        elif key == "slots":
            for i in range(res.n_vanes):
                ax.plot(t, res.vanes["slot1"][i], lw=1, label=f"F1 vane {i}")
                ax.plot(t, res.vanes["slot2"][i], lw=1, ls="--", label=f"F2 vane {i}")
        else:
            scale = {"s": 1e3, "penetration": 1e6}.get(key, 1.0)
            for i in range(res.n_vanes):
                ax.plot(t, res.vanes[key][i] * scale, lw=1, label=f"vane {i}")
        ax.set_ylabel(label, fontsize=8)
        if key != "step":
            ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(alpha=0.3)
    if res.n_vanes <= 4:
        axes[1].legend(fontsize=7, ncol=min(4, res.n_vanes))
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{res.model} model, {res.mode} drive", fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=str(path).rsplit(".", 1)[-1] if "." in str(path) else "png", dpi=110)
    plt.close(fig)
