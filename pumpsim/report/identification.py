"""The identification report, and the fit figures the diagnosis report shares with it: the model
over the measurement, the residual with its order spectrum and synchronous average, the iterations.
Every parameter is shown with its unit and "±" for one standard error exactly as the terminal output
does (`presentation.PLUS_MINUS`). When the residual is not white the intervals are flagged as
optimistic, with the AR(1) inflation factor that would widen them -- or, where the identification
already widened them (residual-aware standard errors), by how much and why."""
from __future__ import annotations

import html
import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import MaxNLocator

from ..signals import order_spectrum, synchronous_average
from ..presentation import (OPTIMISTIC, PLUS_MINUS, describe, display_scale, fmt_estimate, fmt_interval,
                            fmt_number)
from .html import Cell, figure_html, nb, provenance_html, provenance_line, provenance_of, table, write_page
from .simulation import tidy_axis, wrapped_angle

RPM = 60 / (2 * math.pi)

def ar1(r) -> float:
    r = np.asarray(r, dtype=float) - np.mean(r)
    return float(np.dot(r[1:], r[:-1]) / max(np.dot(r, r), 1e-300))


def interval_warning(white: bool, runs_p: float, lb_p: float, residual=None) -> str:
    """The standard errors assume independent errors; a correlated residual makes them too small."""
    if white:
        return ""
    extra = ""
    if residual is not None and len(residual) > 2:
        rho = ar1(residual)
        if rho > 0:
            extra = (f" The residual's lag-1 autocorrelation is {rho:.2f}: for AR(1) errors the standard "
                     f"errors are too small by about √((1+ρ)/(1−ρ)) = "
                     f"{math.sqrt((1 + rho) / (1 - rho)):.2g}×.")
    return (f"<p class=warn><b>Intervals are optimistic.</b> Runs test p = {runs_p:.3g}, Ljung–Box p = "
            f"{lb_p:.3g}: {html.escape(OPTIMISTIC)}; the model misses something systematic.{extra}</p>")


def param_row(name, value, stderr, lower=None, upper=None, start=None, harmonics=None):
    """(parameter, meaning, unit, start, estimate ± s.e., 95 % interval) in display units."""
    label, unit = describe(name, harmonics)
    f, shown = display_scale(unit, value)
    sc = (lambda v: None if v is None else v * f)
    est = fmt_estimate(sc(value), sc(stderr))
    extra = ""
    if unit == "rad" and value is not None:
        extra = f" ({math.degrees(value):.4g}°)"
    elif unit == "rad/s" and value is not None:
        extra = f" ({value * RPM:.6g} rpm)"
    ci = "—" if value is None else fmt_interval(sc(lower), sc(upper), sc(stderr))
    return [Cell(name), Cell(label), Cell(shown),
            Cell(fmt_number(sc(start)) if start is not None else "—", True),
            Cell(nb(est + extra), True, raw=True), Cell(nb(ci), True, raw=True)]


PARAM_HEADERS = ["parameter", "meaning", "unit", "start", "estimate ± s.e.", "95 % interval"]


def segments(res, data=None) -> list:
    """The measurements inside a result as (slice, speed [rad/s], label): one for a single fit;
    for a joint fit the rows of each Dataset in `data` (the speed from the fitted angle, since the
    result carries the first measurement's only)."""
    n = len(res.time)
    sizes = [d.n for d in data] if isinstance(data, (list, tuple)) and all(hasattr(d, "n") for d in data) else []
    if len(sizes) < 2 or sum(sizes) != n:
        return [(slice(0, n), float(res.speed), "")]
    out, lo = [], 0
    theta, t = np.asarray(res.angle, dtype=float), np.asarray(res.time, dtype=float)
    for i, m in enumerate(sizes):
        sl = slice(lo, lo + m)
        w = abs(theta[sl][-1] - theta[sl][0]) / max(t[sl][-1] - t[sl][0], 1e-300)
        out.append((sl, w, f"measurement {i + 1} ({w:.4g} rad/s)"))
        lo += m
    return out


def signal_of(res) -> tuple[str, str]:
    """What a result fitted: the drive torque, or the speed for a transient (run-up) fit."""
    transient = "transient" in str(getattr(res, "method", ""))
    return ("rotor speed ω", "rad/s") if transient else ("drive torque τ", "N·m")


def residual_figures(res, data=None, title="residual"):
    """Residual in time, in shaft orders and as an angle-domain average (one figure); a joint
    fit's measurements each with their own speed and colour."""
    t, residual, angle = (np.asarray(x, dtype=float) for x in (res.time, res.residual, res.angle))
    segs = segments(res, data)
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.1))
    unit = signal_of(res)[1]
    milli = unit == "N·m" and np.nanmax(np.abs(residual)) < 0.1
    k = 1e3 if milli else 1.0
    u = "mN·m" if milli else unit
    top = 0.0
    for j, (sl, w, label) in enumerate(segs):
        color = "0.25" if len(segs) == 1 else f"C{j}"
        ax[0].plot(t[sl], residual[sl] * k, lw=0.5, color=color, label=label or None)
        sp = order_spectrum(residual[sl], t[1] - t[0], w)
        ax[1].plot(sp["order"], sp["amplitude"] * k, lw=0.8, color=f"C{j}", label=label or None)
        top = max(top, min(40, sp["order"].max()))
        for pk in [p for p in sp["peaks"] if p["order"] <= 40][:5]:
            ax[1].annotate(f"{pk['order']:.2f}", (pk["order"], pk["amplitude"] * k), fontsize=7,
                           xytext=(2, 2), textcoords="offset points")
        if abs(angle[sl][-1] - angle[sl][0]) >= 2 * math.pi:
            sa = synchronous_average(residual[sl], angle[sl])
            ax[2].plot(np.degrees(sa["angle"]), sa["average"] * k, color=f"C{j}", label=label or None)
        else:
            ax[2].text(0.5, 0.5, "less than one revolution:\nno average", ha="center", va="center",
                       transform=ax[2].transAxes, fontsize=9)
    ax[0].set_xlabel("time [s]" + (" (measurements one after the other)" if len(segs) > 1 else ""))
    ax[0].set_ylabel(f"{title} [{u}]")
    ax[0].set_title("residual (measured − model)", fontsize=9)
    ax[1].set_xlim(0, top)
    hz = ", ".join(f"{w / (2 * math.pi):.4g}" for _, w, _ in segs)
    ax[1].set_xlabel(f"shaft order (1 = {hz} Hz)")
    ax[1].set_ylabel(f"amplitude [{u}]")
    ax[1].set_title("order spectrum (Hann window)", fontsize=9)
    ax[2].set_xlim(0, 360)
    ax[2].set_xticks(range(0, 361, 90))
    ax[2].set_xlabel("rotor angle θ [deg]")
    ax[2].set_ylabel(f"angle-domain average [{u}]")
    ax[2].set_title("synchronous average over revolutions", fontsize=9)
    for a in ax:
        a.grid(alpha=0.3)
        tidy_axis(a)
    if len(segs) > 1:  # below the middle panel's axis label, off the curves
        ax[1].legend(fontsize=7.5, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.28),
                     ncol=len(segs))
    fig.tight_layout()
    return figure_html(fig)


def torque_overlay(res, data=None, label="fitted model", show_initial=True):
    """Measured torque (dots) and the model against the rotor angle in degrees, all revolutions
    overlaid: a steady pump's torque is one curve, not a solid band over time. The model is drawn
    over each measurement's last revolution (a line per revolution would smear the torque steps)."""
    theta = np.asarray(res.angle, dtype=float)
    deg = np.degrees(np.mod(theta, 2 * math.pi))
    segs = segments(res, data)
    fig, ax = plt.subplots(figsize=(11.5, 3.8))
    turns = []
    for j, (sl, _, name) in enumerate(segs):
        th = theta[sl]
        turns.append(abs(th[-1] - th[0]) / (2 * math.pi))
        last = np.abs(th - th[0]) >= abs(th[-1] - th[0]) - 2 * math.pi
        tag = " (last revolution)" if turns[-1] > 1 else ""
        pre = f"{name}: " if name else ""
        d = deg[sl]
        ax.plot(d, np.asarray(res.measured)[sl], ".", ms=1.5, color="0.55" if j == 0 else "0.75",
                label=f"{pre}measured ({len(d)} samples)")
        if show_initial and getattr(res, "initial_model", None) is not None:
            ax.plot(*wrapped_angle(d[last], np.asarray(res.initial_model)[sl][last]), lw=1.0, ls="--",
                    color="C1" if len(segs) == 1 else f"C{j}", label=f"{pre}initial model{tag}")
        ax.plot(*wrapped_angle(d[last], np.asarray(res.fitted)[sl][last]), color=f"C{j}", lw=1.3,
                label=f"{pre}{label}{tag}")
    ax.set_xlim(0, 360)
    ax.set_xticks(range(0, 361, 45))
    ax.set_xlabel(f"rotor angle θ [deg] ({' + '.join(f'{x:.3g}' for x in turns)} revolutions overlaid)")
    ax.set_ylabel("drive torque τ [N·m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize=8, markerscale=5)
    ax.grid(alpha=0.3)
    tidy_axis(ax)
    fig.tight_layout()
    return figure_html(fig)


def time_plot(res):
    """Measured, initial and fitted signal against time (a run-up: the speed changes)."""
    name, unit = signal_of(res)
    fig, ax = plt.subplots(figsize=(11.5, 3.6))
    ax.plot(res.time, res.measured, ".", ms=1.5, color="0.55", label="measured")
    if getattr(res, "initial_model", None) is not None:
        ax.plot(res.time, res.initial_model, "C1--", lw=1.0, label="initial model")
    ax.plot(res.time, res.fitted, "C0", lw=1.2, label="fitted model")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{name} [{unit}]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize=8, markerscale=5)
    ax.grid(alpha=0.3)
    tidy_axis(ax)
    fig.tight_layout()
    return figure_html(fig)


def _status(res) -> str:
    d = res.diagnostics
    cls = "ok" if res.converged and d["white_at_5pct"] and not res.unidentifiable else "warn"
    return (f"<p class={cls}>{html.escape(res.method)}: <b>{'converged' if res.converged else 'NOT converged'}</b>"
            f" ({html.escape(res.message)}), {len(res.iterations) - 1} iterations, residual RMS "
            f"{nb(format(res.rms, '.4g') + ' ' + signal_of(res)[1])}, residual "
            f"{'white' if d['white_at_5pct'] else '<b>not white</b>'} at 5 %, "
            f"{res.wall_time:.2f} s.</p>") + "".join(
        f"<p class=warn><b>Not a usable estimate</b>: {html.escape(p)}</p>" for p in res.problems())


# -- identification --------------------------------------------------------------------------------

def identification_report(res, path, title="pumpsim identification", cfg=None, data=None,
                          provenance_rows=None) -> None:
    """Write the HTML report of an IdentificationResult to `path`.

    cfg: the PumpConfig fitted (names, harmonic orders, kernel key for the provenance block);
    data: the Dataset(s) or file path(s) fitted (file name and SHA-256); provenance_rows replaces
    the computed provenance."""
    harmonics = getattr(cfg, "harmonics", None)
    rows_p = provenance_rows if provenance_rows is not None else provenance_of(res, cfg, data)
    parts = [f"<h1>{html.escape(title)}</h1>", provenance_line(rows_p), _status(res)]
    if res.unidentifiable:
        parts.append(f"<p class=warn>Not identifiable from this data (no number given): "
                     f"{html.escape(', '.join(res.unidentifiable))}</p>")
    d = res.diagnostics
    if res.intervals is not None and res.intervals.basis == "residual-aware":  # already widened: say by what
        parts += [f"<p class=warn><b>Intervals widened.</b> {html.escape(n.removeprefix('intervals: '))}</p>"
                  for n in res.interval_notes()]
    else:
        parts.append(interval_warning(d["white_at_5pct"], d["runs_test"]["p_value"], d["ljung_box"]["p_value"],
                                      res.residual))
    if res.adequacy is not None:
        cls = {"adequate": "ok", "systematic": "note", "inadequate": "warn"}[res.adequacy.verdict]
        parts.append(f"<h2>Model adequacy: {res.adequacy.verdict}</h2><p class={cls}>"
                     + "<br>".join(html.escape(line.strip()) for line in res.adequacy.summary().splitlines())
                     + "</p>")
    rows = []
    for e in res.estimates.values():
        rows.append(param_row(e.name, e.value, e.stderr, e.lower95, e.upper95, e.initial, harmonics))
    parts.append("<h2>Parameters</h2>" + table(PARAM_HEADERS, rows)
                 + f"<p class=note>{html.escape(PLUS_MINUS)}. Lengths are shown in mm or µm; "
                   "the config and the JSON are SI.</p>")
    if res.correlation is not None and len(res.correlation) > 1:
        names = [n for n, e in res.estimates.items() if e.identifiable]
        parts.append("<h3>Correlation of the estimates</h3>" + table(
            [""] + names,
            [[Cell(n)] + [Cell(f"{v:+.3f}", True) for v in r] for n, r in zip(names, res.correlation)]))
    if signal_of(res)[1] == "N·m":
        parts.append("<h2>Measured and model torque</h2>" + torque_overlay(res, data))
    else:
        parts.append("<h2>Measured and model speed</h2>" + time_plot(res))
    parts.append("<h2>Iteration history</h2>" + _iteration_figure(res, harmonics))
    parts.append("<h2>Residual</h2><p>" + html.escape(
        f"Runs test p = {d['runs_test']['p_value']:.3g} ({d['runs_test']['runs']} runs), Ljung–Box p = "
        f"{d['ljung_box']['p_value']:.3g} over {d['ljung_box']['lags']} lags: "
        f"{'white' if d['white_at_5pct'] else 'not white'} at 5 %.") + "</p>")
    parts.append(residual_figures(res, data))
    parts.append(provenance_html(rows_p))
    write_page(path, title, parts)


def _iteration_figure(res, harmonics=None):
    names = list(res.iterations[0]["params"])
    fig, ax = plt.subplots(1, len(names) + 1, figsize=(3.3 * (len(names) + 1), 2.9), squeeze=False)
    ax = ax[0]
    its = np.arange(len(res.iterations))
    for a, n in zip(ax, names):
        label, unit = describe(n, harmonics)
        vals = np.array([it["params"][n] for it in res.iterations], dtype=float)
        f, shown = display_scale(unit, float(np.nanmax(np.abs(vals))) if vals.size else None)
        a.plot(its, vals * f, "o-", ms=4)
        a.set_title(f"{n} [{shown}]", fontsize=9)
        tidy_axis(a, vals * f)
    rms = np.array([max(it["rms"], 1e-300) for it in res.iterations])
    unit = signal_of(res)[1]
    if rms.max() / rms.min() > 30:
        ax[-1].semilogy(its, rms, "o-", ms=4, color="k")
        ax[-1].set_title(f"residual RMS [{unit}]", fontsize=9)
    else:
        milli = unit == "N·m" and rms.max() < 0.1
        ax[-1].plot(its, rms * (1e3 if milli else 1.0), "o-", ms=4, color="k")
        ax[-1].set_title(f"residual RMS [{'mN·m' if milli else unit}]", fontsize=9)
        tidy_axis(ax[-1])
    for a in ax:
        a.set_xlabel("iteration")
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
        a.grid(alpha=0.3)
    fig.tight_layout()
    return figure_html(fig)
