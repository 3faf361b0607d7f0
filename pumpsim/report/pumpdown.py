"""Pump-down figures and HTML report: booster pressure with the target, current and speed, where
the energy goes, one cell's indicator (p-V) diagram at several booster pressures, the torque split
into gas and friction (and inertia, the rest) over a revolution, and the pumping speed S(p) with
the ultimate pressure. The report opens with the operating conditions (supply voltage, booster
volume, pressures, leak) and ends with the provenance block. Every legend sits outside its axes
(it covers no curve) and every reference line is named in it.
"""
from __future__ import annotations

import html
import math

import numpy as np

from ..io import atomic_path
from ..presentation import provenance

RPM = 30 / math.pi


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


def _legend(ax, handles=None, ncol=2):
    """Below the axes: it never covers a curve."""
    kw = {} if handles is None else {"handles": handles}
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=ncol, fontsize=8, frameon=False, **kw)


def _pressure_panel(a, res):
    s, t = res.summary, res.time
    a.plot(t, res.columns["booster_pressure"] / 1e3, "C0", label="booster pressure (full model)")
    fp = s.get("fast_path")
    if fp:
        a.plot(fp["time"], np.array(fp["booster_pressure"]) / 1e3, "C3--", lw=1.2,
               label="fast path (cycle-averaged maps)")
    if s.get("target_pressure"):
        a.axhline(s["target_pressure"] / 1e3, color="k", ls="--", lw=0.8,
                  label=f"target {s['target_pressure'] / 1e3:.4g} kPa")
    if s.get("time_to_target") is not None:
        a.axvline(s["time_to_target"], color="C0", ls=":", lw=1.0,
                  label=f"target reached at {s['time_to_target']:.3g} s")
    a.set(xlabel="time [s]", ylabel="booster pressure [kPa]", title="Booster pump-down", ylim=(0, None))
    _legend(a)


def _current_panel(a, res):
    """Current (left axis) and speed (right axis), one legend for both."""
    s, t, c = res.summary, res.time, res.columns
    if s["peak_current"] is None:  # no motor: the speed alone
        h = a.plot(t, c["speed"] * RPM, "C2", lw=1.0, label=f"rotor speed (set; mean {s['mean_speed_rpm']:.0f} rpm)")
        a.set(xlabel="time [s]", ylabel="rotor speed [rpm]", title="Speed (no motor)", ylim=(0, None))
        _legend(a, h, ncol=1)
        return
    h1 = a.plot(t, c["current"], "C1", lw=0.8,
                label=f"motor current (peak {s['peak_current']:.1f} A, mean {s['mean_current']:.2f} A)")
    a.set(xlabel="time [s]", ylabel="motor current [A]", title="Current and speed")
    b = a.twinx()
    h2 = b.plot(t, c["speed"] * RPM, "C2", lw=1.0, label=f"rotor speed (mean {s['mean_speed_rpm']:.0f} rpm)")
    b.set_ylabel("rotor speed [rpm]", color="C2")
    b.set_ylim(0, None)
    a.set_ylim(0, None)
    _legend(a, h1 + h2, ncol=1)


def energy_parts(s) -> list[tuple[str, float]]:
    """(label, J) summing to the supply's energy (the shaft work's without a motor): the shaft
    work's parts (work_split) with the motor's losses, and the kinetic energy the run leaves in
    rotor, vanes and motor (and the winding's L i^2 / 2) as what remains."""
    from ..pneumatics.pumpdown import work_split

    names = {"gas": "gas work", "friction": "vane friction (tips, slots)", "valve damping": "valve damping",
             "contacts": "contact work"}
    shaft = [(names[n], v) for n, v in work_split(s) if n != "kinetic"]
    if s["energy"] is None:
        return shaft + [("kinetic (rotor, vanes)", s["shaft_work"] - sum(v for _, v in shaft))]
    motor = [("copper loss R i²", s["copper_loss"]), ("motor friction", s["motor_friction_work"])]
    rest = s["energy"] - sum(v for _, v in shaft + motor)
    return shaft + motor + [("kinetic (rotor, vanes, motor)", rest)]


def _energy_panel(a, res):
    s = res.summary
    parts = energy_parts(s)
    q = np.array([v for _, v in parts])
    a.barh([n for n, _ in parts], q, color=[f"C{k}" for k in range(len(parts))])
    for y, v in enumerate(q):
        a.text(max(v, 0.0), y, f" {v:.1f} J", va="center", fontsize=8)
    a.set_xlim(min(0.0, 1.2 * q.min()), 1.2 * max(q.max(), 1e-300))
    a.set(xlabel="energy over the run [J]", title=f"Where the {s['energy']:.1f} J from the supply go"
          if s["energy"] is not None else f"Where the {s['shaft_work']:.1f} J of shaft work go (no motor)")


def _indicator_panel(a, maps, cfg, picks):
    for d in picks:
        a.plot(d["volume"] * 1e6, d["pressure"] / 1e3, label=f"booster at {d['booster_pressure'] / 1e3:.0f} kPa")
    atm = cfg.pneumatic.values["gas.atmosphere"] / 1e3
    a.axhline(atm, color="k", lw=0.7, ls=":", label=f"atmosphere {atm:.1f} kPa")
    a.set(xlabel="cell volume [cm³]", ylabel="cell 0 pressure [kPa]", title="Indicator diagram (cell 0)")
    _legend(a)


def _torque_panel(a, d):
    deg = np.degrees(d["angle"])
    a.plot(deg, d["torque"], "k", label="shaft torque")
    a.plot(deg, d["gas_torque"], "C0", label="gas torque")
    a.plot(deg, d["friction_torque"], "C3", label="friction torque")
    # the rest: the vanes' kinetic energy swinging in and out over a revolution (and the
    # rotor's acceleration); without it the parts do not add up to the shaft torque
    a.plot(deg, d["torque"] - d["gas_torque"] - d["friction_torque"], "C7:", label="inertia (the rest)")
    a.axhline(0, color="0.5", lw=0.6)
    a.set(xlabel="rotor angle [deg]", ylabel="torque [N·m]", xlim=(deg.min(), deg.max()),
          title=f"Torque split over a revolution (booster {d['booster_pressure'] / 1e3:.0f} kPa)")
    _legend(a)


def _speed_panel(a, maps, cfg):
    from ..pneumatics.pumpdown import leak_flow

    v = cfg.pneumatic.values
    p_u, extrap = ultimate_pressure(maps, lambda p: leak_flow(v, p))
    a.plot(maps.pressure / 1e3, maps.pumping_speed * 6e4, "C0o-", label="S(p), cycle averages")
    a.axvline(p_u / 1e3, color="C3", ls="--",
              label=f"ultimate pressure {p_u / 1e3:.1f} kPa" + (" (extrapolated)" if extrap else ""))
    a.set(xlabel="booster pressure [kPa]", ylabel="pumping speed [L/min]", title="Pumping speed",
          xlim=(0, None), ylim=(0, None))
    _legend(a, ncol=1)


def pumpdown_panels(res, maps, cfg):
    """The report's six panels (the lower three need the maps); returns (figure, pyplot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 3, figsize=(14, 10), layout="constrained")
    _pressure_panel(ax[0, 0], res)
    _current_panel(ax[0, 1], res)
    _energy_panel(ax[0, 2], res)
    if maps is not None:
        picks = _picks(maps.revolutions)
        _indicator_panel(ax[1, 0], maps, cfg, picks)
        _torque_panel(ax[1, 1], picks[len(picks) // 2])
        _speed_panel(ax[1, 2], maps, cfg)
    else:
        for a in ax[1]:
            a.axis("off")
    for a in ax.ravel():
        if a.axison:
            a.grid(alpha=0.3)
    fig.suptitle(f"pumpsim pump-down: {res.name}")
    return fig, plt


def _picks(revs, n=4):
    idx = np.unique(np.linspace(0, len(revs) - 1, n).round().astype(int))
    return [revs[i] for i in idx]


def pumpdown_figure(res, maps, cfg, path) -> None:
    fig, plt = pumpdown_panels(res, maps, cfg)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)


def operating_conditions(res, cfg) -> list[tuple[str, str]]:
    """What the pump-down ran at: supply, booster, gas and the model."""
    s, v = res.summary, cfg.pneumatic.values
    model = "Model 1 (vanes free in their slots, penalty contacts)" if s.get("model") == "contact" else \
        "Model 2 (vane tips on the housing)"
    rows = [("configuration", cfg.name), ("model", f"{model}, {cfg.vanes} vanes")]
    if cfg.pneumatic.motor:
        rows += [("supply voltage", f"{v['motor.voltage']:.4g} V"),
                 ("motor", f"R = {v['motor.resistance'] * 1e3:.4g} mΩ, k = {v['motor.constant'] * 1e3:.4g} mN·m/A")]
    else:
        rows.append(("drive", f"speed prescribed, {cfg.speed * RPM:.0f} rpm"))
    rows += [("booster volume", f"{v['booster.volume'] * 1e3:.4g} L"),
             ("booster pressure: start → target", f"{s['start_pressure'] / 1e3:.4g} kPa → "
              + (f"{s['target_pressure'] / 1e3:.4g} kPa" if s.get("target_pressure") else "no target")),
             ("booster leak", f"{v['booster.leak'] * 1e6:.4g} mg/s at full vacuum"),
             ("atmosphere, gas temperature", (f"{v['gas.atmosphere'] / 1e3:.4g} kPa, "
              f"{v['gas.temperature'] - 273.15:.4g} °C"))]
    return rows


def _kernel_key(cfg, model) -> str | None:
    try:
        from ..kernels import load_kernels
        from ..kernels.pneumatic import structure_of

        st = structure_of(cfg, model)
        return f"{st.variant}-{load_kernels(st, build=False).key}"
    except Exception:  # provenance must never break a report  # noqa: BLE001
        return None


def result_rows(res) -> list[tuple[str, str]]:
    s = res.summary
    rows = [("time to target", _fmt(s["time_to_target"], "s")),
            ("final booster pressure", f"{s['final_pressure'] / 1e3:.2f} kPa"),
            ("peak / mean current", f"{s['peak_current']:.1f} A / {s['mean_current']:.2f} A"
             if s["peak_current"] is not None else "no motor"),
            ("energy from the supply", f"{s['energy']:.1f} J" if s["energy"] is not None else "no motor"),
            work_row(s),
            ("mean speed", f"{s['mean_speed_rpm']:.0f} rpm")]
    fp = s.get("fast_path")
    if fp:
        rows.append(("fast path: time to target / mean current",
                     f"{_fmt(fp['time_to_target'], 's')} / "
                     + (f"{fp['mean_current']:.2f} A" if fp["mean_current"] is not None else "no motor")))
    st = s["solver"]
    rows.append(("CVODES", f"{st['nsteps']} steps, {st['njevals']} Jacobians, {st['wall_time']:.1f} s wall"))
    return rows


def pumpdown_report(res, maps, cfg, path) -> None:
    from .html import (
        figure_html,
        provenance_html,
        provenance_line,
        table,
        write_page,
    )

    prov = provenance(cfg, kernel_key=_kernel_key(cfg, res.summary.get("model", "constrained")))
    fig, _ = pumpdown_panels(res, maps, cfg)
    parts = [f"<h1>Pump-down: {html.escape(res.name)}</h1>", provenance_line(prov),
             *[f"<p class=warn>{html.escape(w)}</p>" for w in res.warnings],
             "<h2>Operating conditions</h2>", table(["input", "value"], operating_conditions(res, cfg)),
             "<h2>Results</h2>", table(["result", "value"], result_rows(res)),
             "<h2>Figures</h2>", figure_html(fig), provenance_html(prov)]
    write_page(path, f"pump-down {res.name}", parts)


def work_row(s) -> tuple[str, str]:
    """The report's shaft-work row: every part, so that the equation closes (pumpdown.work_split)."""
    from ..pneumatics.pumpdown import work_split

    parts = work_split(s)
    return ("shaft work = " + " + ".join(name for name, _ in parts),
            f"{s['shaft_work']:.1f} J = " + " + ".join(f"{v:.4g}" for _, v in parts) + " J")


def _fmt(v, unit):
    return "not reached" if v is None else f"{v:.3f} {unit}"
