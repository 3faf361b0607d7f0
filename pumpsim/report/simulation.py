"""Simulation figures an engineer reads at a glance (report Figures 29-35, redrawn).

Per-vane signals and the drive torque are drawn against the rotor angle in degrees with every
revolution overlaid (the last complete one bold), so a steady state is one curve and a transient a
band; `x="time"` draws them against time instead. Vanes whose curves coincide (on an ellipse vane i
and vane i + N/2 see the same housing) are drawn once and labelled "vane 0 = vane 2", so every
legend entry names a visible line. Legends sit outside the axes. A summary row gives the torque's
ripple (peak-to-peak over the last complete revolution) and its shaft-order spectrum from an
angle-domain resampling of whole revolutions. The contact model adds penetration and the step size.

Reads a result only through its spec §7 column names (`res["s_0"]`), `n_vanes`, `model`, `mode`
and, for the step-size panel, `extra["step_time"]`/`extra["step"]`.
"""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import MaxNLocator, MultipleLocator, ScalarFormatter  # noqa: E402

from ..io import atomic_path  # noqa: E402
from ..tolerances import FLAT_RTOL, IDENTICAL_RTOL  # noqa: E402

RPM = 60 / (2 * math.pi)
FORMATS = ("png", "svg", "pdf")
# per-vane panels: column, axis label, scale to the unit shown
VANE_PANELS = [("s", "vane extension s [mm]", 1e3), ("normal", "housing normal force N [N]", 1.0)]
SLOT_PANEL = ("slot forces F1, F2 [N]", ("slot1", "slot2"))
SLOT_NAMES = {"slot1": "F1 (bottom end)", "slot2": "F2 (slot mouth)"}
MODEL_TITLE = {"constrained": "constrained model (Model 2)", "contact": "contact model (Model 1)"}


def figure_format(path) -> str:
    """The figure format from the file name (.png, .svg, .pdf; no extension: PNG); anything else
    is bad input, refused before any work."""
    name = str(path).replace("\\", "/").rsplit("/", 1)[-1]
    ext = name.rsplit(".", 1)[-1].lower() if "." in name else "png"
    if ext not in FORMATS:
        from ..errors import ConfigError

        raise ConfigError(f"figure '{path}': format '.{ext}' is not supported; use one of "
                          + ", ".join("." + f for f in FORMATS))
    return ext


def _column(res, name):
    try:
        return np.asarray(res[name], dtype=float)
    except (KeyError, IndexError):
        return None


def tidy_axis(ax, values=None, axis="y"):
    """Plain tick labels (no offset, no 13-digit labels) and, for a (nearly) constant signal,
    limits a few per cent around its value instead of a zoom into rounding noise."""
    fmt = ScalarFormatter(useOffset=False)
    fmt.set_powerlimits((-3, 4))
    (ax.yaxis if axis == "y" else ax.xaxis).set_major_formatter(fmt)
    if values is None:
        return
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    lo, hi = float(v.min()), float(v.max())
    mid, size = 0.5 * (lo + hi), max(abs(lo), abs(hi))
    if hi - lo <= 1e-6 * max(size, 1e-300):
        half = 0.05 * abs(mid) if mid != 0 else 1.0
        (ax.set_ylim if axis == "y" else ax.set_xlim)(mid - half, mid + half)


def wrapped_angle(x, y):
    """Break a line where the angle wraps from 360 back to 0 (NaN gaps)."""
    jump = np.nonzero(np.abs(np.diff(x)) > 180)[0] + 1
    return np.insert(x, jump, np.nan), np.insert(y, jump, np.nan)


def vane_groups(curves, rtol=IDENTICAL_RTOL):
    """Indices of vanes grouped by identical curves: [[0, 2], [1, 3]] on a 4-vane ellipse."""
    scale = max(float(np.nanmax(np.abs(curves))) if curves.size else 0.0, 1e-300)
    groups = []
    for i in range(len(curves)):
        for g in groups:
            if np.nanmax(np.abs(curves[i] - curves[g[0]])) <= rtol * scale:
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def group_label(g) -> str:
    return " = ".join(f"vane {i}" for i in g)


class _Drawer:
    """Draws a signal against the rotor angle (revolutions overlaid, the last 360° of rotation
    bold, earlier ones faint) or against time."""

    def __init__(self, res, x: str):
        self.x = x
        self.t = _column(res, "time")
        theta = _column(res, "angle")
        turn = np.abs(theta - theta[0])
        self.turns = float(turn[-1] / (2 * math.pi))
        # under one revolution nothing overlays: the axis is the angle travelled (unwrapped)
        self.overlay = self.turns >= 1
        self.rel = np.degrees(np.mod(theta, 2 * math.pi) if self.overlay else theta)
        self.bold = turn >= turn[-1] - 2 * math.pi * (1 + 1e-9)

    def plot(self, ax, y, **style):
        if self.x == "time":
            ax.plot(self.t, y, **style)
            return
        if self.turns > 1:
            ax.plot(*wrapped_angle(self.rel, y), **dict(style, lw=0.7, alpha=0.35))
        ax.plot(*wrapped_angle(self.rel[self.bold], y[self.bold]), **dict(style, lw=style.get("lw", 1.4)))

    def finish(self, ax):
        if self.x == "time":
            tidy_axis(ax, axis="x")
            return
        if self.overlay:
            ax.set_xlim(0, 360)
            ax.xaxis.set_major_locator(MultipleLocator(45))
            ax.xaxis.set_minor_locator(MultipleLocator(15))
        else:
            ax.set_xlim(self.rel.min(), self.rel.max())
            tidy_axis(ax, axis="x")


def torque_orders(res, max_order=None):
    """Peak-to-peak, mean and shaft-order amplitudes of the drive torque from whole revolutions,
    resampled uniformly in rotor angle (exact orders at any speed, constant or not)."""
    theta = _column(res, "angle")
    tq = _column(res, "torque")
    sign = 1.0 if theta[-1] >= theta[0] else -1.0
    th = sign * (theta - theta[0])
    turns = th[-1] / (2 * math.pi)
    n_rev = int(math.floor(turns + 1e-9))
    out = {"revolutions": turns, "whole": n_rev}
    if n_rev < 1:
        out.update(ptp=float(np.ptp(tq)), mean=float(np.mean(tq)), orders=None, amplitudes=None)
        return out
    start = th[-1] - 2 * math.pi * n_rev
    per_rev = max(64, int(2 ** math.ceil(math.log2(max(np.sum(th >= th[-1] - 2 * math.pi), 2)))))
    grid = start + np.arange(n_rev * per_rev) * (2 * math.pi / per_rev)
    tq_a = np.interp(grid, th, tq)
    last = tq_a[-per_rev:]
    spec = np.fft.rfft(tq_a) / tq_a.size
    k = np.arange(0, min(spec.size, (max_order or per_rev // 2) * n_rev + 1), n_rev)
    amp = 2 * np.abs(spec[k])
    amp[0] = abs(spec[0].real)
    out.update(ptp=float(np.ptp(last)), mean=float(np.mean(tq_a)), rms_ripple=float(np.std(last)),
               orders=k // n_rev, amplitudes=amp)
    return out


def title_of(res, name=None) -> str:
    speed = _column(res, "speed")
    w = float(np.mean(speed))
    model = MODEL_TITLE.get(getattr(res, "model", ""), getattr(res, "model", ""))
    drive = getattr(res, "mode", "speed")
    if drive == "speed":
        spd = f"{w:.4g} rad/s ({w * RPM:.5g} rpm)"
    else:
        spd = f"mean {w:.4g} rad/s ({w * RPM:.5g} rpm), {np.ptp(speed) * RPM:.3g} rpm peak-to-peak"
    name = name or getattr(res, "config_name", None) or "pump"
    return f"{name}: {model}, {drive} drive at {spd}, {res.n_vanes} vane(s)"


def _legend(ax, handles=None, **kw):
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5, frameon=False,
              borderaxespad=0.0, **kw)


def plot_simulation(res, path, name: str | None = None, x: str = "angle") -> None:
    """Write the figure set of a simulation result to `path` (.png, .svg or .pdf).

    name: the configuration's name for the title; x: "angle" (rotor angle in degrees, revolutions
    overlaid; the default) or "time"."""
    fmt = figure_format(path)
    fig = simulation_figure(res, name=name, x=x)
    with atomic_path(path) as tmp, plt.rc_context({"svg.fonttype": "none"}):  # SVG text stays text
        fig.savefig(tmp, format=fmt, dpi=110, bbox_inches="tight")
    plt.close(fig)


def simulation_figure(res, name: str | None = None, x: str = "angle"):
    if x not in ("angle", "time"):
        raise ValueError(f"x must be 'angle' or 'time', got {x!r}")
    n = res.n_vanes
    penetration = _column(res, "penetration_0") is not None
    extra = getattr(res, "extra", {}) or {}
    has_steps = "step" in extra and "step_time" in extra and len(extra["step"]) > 0
    gas = _column(res, "pressure_0") is not None  # spec §8: the gas-coupled models' cells
    driven = getattr(res, "mode", "speed") != "speed"
    rows = ["s", "normal", "slots", "torque"] + (["pressure"] if gas else []) + (["speed"] if driven else []) \
        + (["current"] if gas and driven else []) + (["penetration"] if penetration else []) \
        + (["step"] if has_steps else []) + ["summary"]
    heights = [2.0] * (len(rows) - 1) + [0.3, 2.4]  # a spacer keeps the x label off the summary
    total = sum(heights) + 1.0
    fig = plt.figure(figsize=(11.5, total))
    gs = fig.add_gridspec(len(heights), 1, height_ratios=heights, hspace=0.3, left=0.08, right=0.78,
                          top=1 - 0.55 / total, bottom=0.45 / total)
    d = _Drawer(res, x)
    xlabel = ("time [s]" if x == "time" else "rotor angle θ [deg] (revolutions overlaid; the last 360° bold)"
              if d.overlay else f"rotor angle θ [deg] ({d.turns:.3g} of a revolution simulated)")
    axes = _panel_axes(fig, gs, rows)
    # one colour per vane, the same in every panel (beyond ten vanes from a colour map)
    colors = [f"C{i}" for i in range(n)] if n <= 10 else [plt.cm.turbo(i / (n - 1)) for i in range(n)]
    for col, label, scale in VANE_PANELS:
        _vane_panel(axes[col], d, res, colors, col, label, scale)
    if penetration:
        _vane_panel(axes["penetration"], d, res, colors, "penetration", "penetration δ [µm]", 1e6)
    _slot_panel(axes["slots"], d, res, colors)
    orders = torque_orders(res)
    _torque_panel(axes["torque"], d, res, orders)
    if gas:
        _gas_panels(axes, d, res, colors)
    if "speed" in axes:
        _signal_panel(axes["speed"], d, _column(res, "speed") * RPM, "rotor speed [rpm]", "C2")
    if has_steps:
        ax = axes["step"]
        ax.semilogy(extra["step_time"], extra["step"], "k.", ms=2)
        ax.set_ylabel("integrator step [s]", fontsize=8.5)
        ax.set_xlabel("time [s]", fontsize=8.5)
        tidy_axis(ax, axis="x")
    _finish_shared_axes(axes, rows, d, xlabel)
    _summary(fig, gs[len(heights) - 1, 0], res, orders)
    fig.suptitle(title_of(res, name), fontsize=11, y=1 - 0.12 / total, va="top")
    return fig


def _panel_axes(fig, gs, rows) -> dict:
    """One axes per row but the summary; all share x except the step-size panel (over time)."""
    axes = {}
    first = None
    for r, key in enumerate(rows):
        if key == "summary":
            continue
        share = first if key != "step" else None
        ax = fig.add_subplot(gs[r, 0], sharex=share)
        if key != "step" and first is None:
            first = ax
        axes[key] = ax
        ax.grid(alpha=0.3)
    return axes


def _vane_panel(ax, d, res, colors, col, label, scale):
    """One curve per group of identical vanes of the per-vane column col (times scale)."""
    n = len(colors)
    curves = np.array([_column(res, f"{col}_{i}") * scale for i in range(n)])
    groups = vane_groups(curves)
    for g in groups:
        d.plot(ax, curves[g[0]], color=colors[g[0]])
    ax.set_ylabel(label, fontsize=8.5)
    tidy_axis(ax, curves)
    _legend(ax, [Line2D([], [], color=colors[g[0]], lw=1.4, label=group_label(g)) for g in groups])


def _gas_panels(axes, d, res, colors):
    """Cell pressures (cell i between vanes i and i+1, in vane i's colour) with the booster's, and
    the motor current when the motor drives."""
    n = len(colors)
    ax = axes["pressure"]
    cells = np.array([_column(res, f"pressure_{i}") * 1e-3 for i in range(n)])
    for i in range(n):
        d.plot(ax, cells[i], color=colors[i])
    booster = _column(res, "booster_pressure") * 1e-3
    d.plot(ax, booster, color="k", ls="--")
    ax.set_ylabel("cell pressure [kPa]", fontsize=8.5)
    tidy_axis(ax, np.vstack([cells, booster[None, :]]))
    _legend(ax, [Line2D([], [], color=colors[i], lw=1.4, label=f"cell {i} (vanes {i}-{(i + 1) % n})")
                 for i in range(n)] + [Line2D([], [], color="k", ls="--", label="booster")])
    if "current" in axes:
        _signal_panel(axes["current"], d, _column(res, "current"), "motor current [A]", "C3")


def _signal_panel(ax, d, y, label, color):
    """One signal of the whole run (speed, current) in the layout of the vane panels."""
    d.plot(ax, y, color=color)
    ax.set_ylabel(label, fontsize=8.5)
    tidy_axis(ax, y)


def _slot_panel(ax, d, res, colors):
    """The slot forces of each group of identical vanes, one line style per slot column."""
    n = len(colors)
    handles = []
    slot_curves = {c: np.array([_column(res, f"{c}_{i}") for i in range(n)]) for c in SLOT_PANEL[1]}
    for c, ls in zip(SLOT_PANEL[1], ("-", "--")):
        for g in vane_groups(slot_curves[c]):
            d.plot(ax, slot_curves[c][g[0]], color=colors[g[0]], ls=ls)
            handles.append(Line2D([], [], color=colors[g[0]], ls=ls, lw=1.4,
                                  label=f"{SLOT_NAMES[c]} {group_label(g)}"))
    ax.axhline(0, color="0.4", lw=0.6)
    ax.set_ylabel(SLOT_PANEL[0], fontsize=8.5)
    tidy_axis(ax, np.concatenate(list(slot_curves.values())))
    _legend(ax, handles, ncol=1 if len(handles) <= 8 else 2)


def _torque_panel(ax, d, res, orders):
    """The drive torque with its mean."""
    tq = _column(res, "torque")
    d.plot(ax, tq, color="k")
    ax.axhline(orders["mean"], color="C3", ls=":", lw=1.0)
    ax.set_ylabel("drive torque τ [N·m]", fontsize=8.5)
    tidy_axis(ax, tq)
    _legend(ax, [Line2D([], [], color="k", lw=1.4, label="torque"),
                 Line2D([], [], color="C3", ls=":", label=f"mean {orders['mean']:.4g} N·m")])


def _finish_shared_axes(axes, rows, d, xlabel):
    """Finishes the shared-x panels; only the lowest of them carries the x label."""
    for key, ax in axes.items():
        if key == "step":
            continue
        d.finish(ax)
        last_shared = [k for k in rows if k not in ("summary", "step")][-1]
        if key == last_shared:
            ax.set_xlabel(xlabel, fontsize=8.5)
        else:
            ax.tick_params(labelbottom=False)


def _summary(fig, cell, res, orders):
    sub = cell.subgridspec(1, 2, width_ratios=[1.3, 1.0], wspace=0.25)
    ax = fig.add_subplot(sub[0, 0])
    n = res.n_vanes
    flat = orders["ptp"] <= FLAT_RTOL * max(abs(orders["mean"]), 1e-300)
    if orders["orders"] is not None and not flat:
        show = max(4 * n, 12)
        k, amp = orders["orders"][1:show + 1], orders["amplitudes"][1:show + 1]
        milli = amp.max() < 0.1
        ax.bar(k, amp * (1e3 if milli else 1.0), width=0.6,
               color=["C3" if (kk % n == 0 and n > 1) else "0.35" for kk in k])
        ax.set_xlabel("shaft order" + (f" (red: multiples of {n}, the vane-passing orders)" if n > 1 else ""),
                      fontsize=8.5)
        ax.set_ylabel(f"torque amplitude [{'mN·m' if milli else 'N·m'}]", fontsize=8.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlim(0.3, show + 0.7)
        tidy_axis(ax)
        ax.grid(alpha=0.3, axis="y")
        ax.set_title(f"torque orders over {orders['whole']} whole revolution(s)", fontsize=9)
    else:
        why = ("torque constant to rounding: no ripple" if flat else
               "less than one revolution simulated:\nno order spectrum")
        ax.text(0.5, 0.5, why, ha="center", va="center", transform=ax.transAxes, fontsize=9)
        ax.set_axis_off()
    tx = fig.add_subplot(sub[0, 1])
    tx.set_axis_off()
    speed = _column(res, "speed")
    lines = [f"revolutions simulated   {orders['revolutions']:.3g}",
             f"torque mean             {orders['mean']:.4g} N·m",
             f"torque ripple p-p       {0.0 if flat else orders['ptp']:.4g} N·m"
             + ("" if orders["whole"] >= 1 else " (whole run)"),
             f"ripple p-p / mean       {0.0 if flat else orders['ptp'] / abs(orders['mean']) * 100:.3g} %"
             if orders["mean"] else ""]
    if orders["orders"] is not None and not flat:
        top = np.argsort(orders["amplitudes"][1:])[::-1][:3] + 1
        k = 1e3 if orders["amplitudes"][top[0]] < 0.1 else 1.0  # the unit of the bar chart
        lines.append("largest orders          " + ", ".join(
            f"{int(orders['orders'][i])}: {orders['amplitudes'][i] * k:.3g}" for i in top)
            + (" mN·m" if k > 1 else " N·m"))
    if getattr(res, "mode", "speed") != "speed":
        lines.append(f"speed ripple p-p        {np.ptp(speed) * RPM:.4g} rpm")
    normal = np.array([_column(res, f"normal_{i}") for i in range(n)])
    lines.append(f"housing normal force    {normal.min():.3g} … {normal.max():.3g} N")
    if normal.min() < 0:
        lines.append("WARNING: N < 0, a vane would lift off")
    tx.text(0.0, 1.0, "\n".join(x for x in lines if x), va="top", ha="left", family="monospace", fontsize=8.5,
            transform=tx.transAxes)
