"""Pump-down figures and HTML report (spec §8): booster pressure with the target, current and
speed, one cell's indicator (p-V) diagram at several booster pressures, the torque split into gas
and friction (and inertia, the rest) over a revolution, and the pumping speed S(p) with the ultimate pressure."""
from __future__ import annotations

import base64
import html
import io
import math

import numpy as np

from ..io import atomic_path, write_text


def ultimate_pressure(maps, leak_flow) -> tuple[float, bool]:
    """Where the pump's mass flow meets the booster leak, from the maps (interpolated), or
    extrapolated linearly from the two lowest map points (second value True)."""
    net = maps.mass_flow - np.array([leak_flow(p) for p in maps.pressure])
    if net[0] <= 0:
        k = int(np.argmax(net > 0))
        p = np.interp(0.0, net[k - 1:k + 1], maps.pressure[k - 1:k + 1])
        return float(p), False
    slope = (net[1] - net[0]) / (maps.pressure[1] - maps.pressure[0])
    return float(max(maps.pressure[0] - net[0] / slope, 0.0)), True


def _figure(res, maps, cfg):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .pumpdown import _leak_area, _orifice

    s = res.summary
    t = res.time
    c = res.columns
    fig, ax = plt.subplots(2, 3, figsize=(16, 9))
    a = ax[0, 0]
    a.plot(t, c["booster_pressure"] / 1e3, "C0", label="full model")
    if s.get("target_pressure"):
        a.axhline(s["target_pressure"] / 1e3, color="k", ls="--", lw=0.8, label="target")
    if s.get("time_to_target") is not None:
        a.axvline(s["time_to_target"], color="C0", ls=":", lw=0.8)
    fp = s.get("fast_path")
    if fp:
        a.plot(fp["time"], np.array(fp["booster_pressure"]) / 1e3, "C3--", lw=1.2,
               label="fast path (cycle-averaged maps)")
    a.set(xlabel="time [s]", ylabel="booster pressure [kPa]", title="Booster pump-down")
    a.legend()
    a.grid(alpha=0.3)
    a = ax[0, 1]
    a.plot(t, c["current"], "C1", lw=0.8)
    a.set(xlabel="time [s]", ylabel="motor current [A]", title="Current and speed")
    a.grid(alpha=0.3)
    b = a.twinx()
    b.plot(t, c["speed"] * 30 / math.pi, "C2", lw=1.0)
    b.set_ylabel("speed [rpm]", color="C2")
    a.text(0.98, 0.95, f"peak {s['peak_current']:.1f} A, mean {s['mean_current']:.1f} A\n"
           f"energy {s['energy']:.0f} J", transform=a.transAxes, ha="right", va="top")
    a = ax[0, 2]
    q = np.array([s["gas_work"], s["friction_work"], s["copper_loss"], s["motor_friction_work"]])
    names = ["gas work", "vane friction (tips, slots)", "copper loss R i²", "motor friction"]
    a.barh(names, q, color=["C0", "C3", "C1", "C4"])
    a.set(xlabel="energy over the run [J]", title=f"Where the {s['energy']:.0f} J go")
    a.grid(alpha=0.3, axis="x")
    if maps is not None:
        a = ax[1, 0]
        picks = _picks(maps.revolutions)
        for d in picks:
            a.plot(d["volume"] * 1e6, d["pressure"] / 1e3, label=f"booster {d['booster_pressure'] / 1e3:.0f} kPa")
        a.axhline(cfg.pneumatic.values["gas.atmosphere"] / 1e3, color="k", lw=0.6, ls=":")
        a.set(xlabel="cell volume [cm³]", ylabel="cell 0 pressure [kPa]", title="Indicator diagram (cell 0)")
        a.legend()
        a.grid(alpha=0.3)
        a = ax[1, 1]
        d = picks[len(picks) // 2]
        deg = np.degrees(d["angle"])
        a.plot(deg, d["torque"], "k", label="shaft torque")
        a.plot(deg, d["gas_torque"], "C0", label="gas torque")
        a.plot(deg, d["friction_torque"], "C3", label="friction torque")
        # the rest: the vanes' kinetic energy swinging in and out over a revolution (and the
        # rotor's acceleration); without it the parts do not add up to the shaft torque
        a.plot(deg, d["torque"] - d["gas_torque"] - d["friction_torque"], "C7:", label="inertia (the rest)")
        a.set(xlabel="rotor angle [deg]", ylabel="torque [N m]",
              title=f"Torque split over a revolution (booster {d['booster_pressure'] / 1e3:.0f} kPa)")
        a.legend()
        a.grid(alpha=0.3)
        a = ax[1, 2]
        v = cfg.pneumatic.values
        area = _leak_area(v)
        p_u, extrap = ultimate_pressure(maps, lambda p: _orifice(v["gas.atmosphere"], p, area, v))
        a.plot(maps.pressure / 1e3, maps.pumping_speed * 6e4, "C0o-", label="S(p), cycle averages")
        a.axvline(p_u / 1e3, color="C3", ls="--",
                  label=f"ultimate {p_u / 1e3:.1f} kPa" + (" (extrapolated)" if extrap else ""))
        a.set(xlabel="booster pressure [kPa]", ylabel="pumping speed [L/min]", title="Pumping speed",
              xlim=(0, None), ylim=(0, None))
        a.legend()
        a.grid(alpha=0.3)
    else:
        for a in ax[1]:
            a.axis("off")
    fig.suptitle(f"pumpsim pump-down: {res.name}")
    fig.tight_layout()
    return fig, plt


def _picks(revs, n=4):
    idx = np.unique(np.linspace(0, len(revs) - 1, n).round().astype(int))
    return [revs[i] for i in idx]


def pumpdown_figure(res, maps, cfg, path) -> None:
    fig, plt = _figure(res, maps, cfg)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)


def pumpdown_report(res, maps, cfg, path) -> None:
    fig, plt = _figure(res, maps, cfg)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png")
    plt.close(fig)
    img = base64.b64encode(buf.getvalue()).decode()
    s = res.summary
    rows = [("time to target", _fmt(s["time_to_target"], "s")),
            ("final booster pressure", f"{s['final_pressure'] / 1e3:.2f} kPa"),
            ("peak / mean current", f"{s['peak_current']:.1f} A / {s['mean_current']:.2f} A"),
            ("energy from the supply", f"{s['energy']:.1f} J"),
            work_row(s),
            ("mean speed", f"{s['mean_speed_rpm']:.0f} rpm")]
    fp = s.get("fast_path")
    if fp:
        rows.append(("fast path: time to target / mean current",
                     f"{_fmt(fp['time_to_target'], 's')} / {fp['mean_current']:.2f} A"))
    st = s["solver"]
    rows.append(("CVODES", f"{st['nsteps']} steps, {st['njevals']} Jacobians, {st['wall_time']:.1f} s wall"))
    table = "".join(f"<tr><th>{html.escape(a)}</th><td>{html.escape(b)}</td></tr>" for a, b in rows)
    warn = "".join(f"<p class=w>{html.escape(w)}</p>" for w in res.warnings)
    text = (f"<!doctype html><meta charset=utf-8><title>pump-down {html.escape(res.name)}</title>"
            "<style>body{font-family:sans-serif;margin:2em;max-width:1700px}th{text-align:left;"
            "padding-right:2em}td,th{padding:3px}.w{color:#a00}img{max-width:100%}</style>"
            f"<h1>Pump-down: {html.escape(res.name)}</h1>{warn}<table>{table}</table>"
            f"<img alt='pump-down figures' src='data:image/png;base64,{img}'>")
    write_text(path, text)


def work_row(s) -> tuple[str, str]:
    """The report's shaft-work row: every part, so that the equation closes (pumpdown.work_split)."""
    from .pumpdown import work_split

    parts = work_split(s)
    return ("shaft work = " + " + ".join(name for name, _ in parts),
            f"{s['shaft_work']:.1f} J = " + " + ".join(f"{v:.4g}" for _, v in parts) + " J")


def _fmt(v, unit):
    return "not reached" if v is None else f"{v:.3f} {unit}"
