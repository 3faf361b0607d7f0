"""The report of a bench-log identification (spec §10), read in a minute: the verdict (usable or
not, and why; the figures against their specification limits), the identified figures with their
intervals, the config's nominal and the limits, the measured channels against the fitted model
with the residual under each, the fit per channel, the correlation of the estimates and what
experiment would separate what the log cannot, the provenance.

The pieces a bench-log diagnosis page reuses draw plain data, not a fit object:
`channel_figure(time, measured, models, noise)` draws any number of models over the log (e.g. the
nominal model and the refitted one: the gap shown shrinking) with each one's residual;
`channel_table(fits)` the fit per channel; `effects_figure(rows)` each named effect's residual RMS
before and after it is refitted; `figures_table` and `limits_banner` the figures against limits.
"""
from __future__ import annotations

import html
import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from .. import limits as spec
from ..presentation import PLUS_MINUS, describe, engineering_scale, fmt_estimate, fmt_interval, fmt_number
from .html import Cell, figure_html, nb, provenance_html, provenance_line, table, write_page
from .simulation import tidy_axis

RPM = 60 / (2 * math.pi)
# channel -> (name, unit shown, factor from SI)
CHANNELS = {"booster_pressure": ("booster pressure", "kPa abs", 1e-3),
            "current": ("motor current", "A", 1.0),
            "speed": ("rotor speed", "rpm", RPM)}
LOG_SCALE_SPAN = 10.0  # a pressure falling by more than this factor is drawn on a log axis, as read
MISSED = 2.0  # a channel's residual RMS this many noise sigmas or more: the model misses something there


def nominal_values(cfg, names) -> dict:
    """The config's value of each fitted name (mu and mu_slot: the dynamic COFs)."""
    if cfg is None:
        return {}
    alias = {"mu": "friction.housing.dynamic", "mu_slot": "friction.slot.dynamic"}
    gas = cfg.pneumatic.values if getattr(cfg, "pneumatic", None) is not None else {}
    out = {}
    for n in names:
        key = alias.get(n, n)
        v = gas.get(key, cfg.values.get(key))
        if v is not None:
            out[n] = float(v)
    return out


def _shown(name, *values):
    """(factor, unit shown) of a parameter for the values it is shown with."""
    unit = describe(name)[1]
    return engineering_scale(unit, [v for v in values if v is not None])


def _label(name) -> str:
    label = describe(name)[0]
    return label[len(name) + 2:-1] if label.startswith(name + " (") else label


def figures_table(estimates, nominal=None, limits=None, judged=True) -> str:
    """Parameter, meaning, unit, nominal, estimate ± s.e., 95 % interval and, with limits, the
    lower and upper limit and the status (IN/OUT/UNDECIDED; OUT rows highlighted); judged False
    (the fit is not a usable estimate): limits.NOT_JUDGED instead of a status."""
    nominal, limits = nominal or {}, limits or {}
    states = spec.statuses(estimates, limits, judged)
    headers = ["parameter", "meaning", "unit", "nominal (config)", "estimate ± s.e.", "95 % interval"]
    if limits:
        headers += ["lower limit", "upper limit", "specification"]
    rows, classes = [], []
    for e in estimates.values():
        lo, hi = limits.get(e.name, (None, None))
        f, unit = _shown(e.name, e.value, e.initial, nominal.get(e.name), lo, hi)
        sc = (lambda v: None if v is None else v * f)
        est = fmt_estimate(sc(e.value), sc(e.stderr)) if e.identifiable and e.value is not None else \
            "not identifiable from this log"
        ci = fmt_interval(sc(e.lower95), sc(e.upper95), sc(e.stderr)) if e.value is not None else "—"
        row = [Cell(e.name), Cell(_label(e.name)), Cell(unit), Cell(fmt_number(sc(nominal.get(e.name))), True),
               Cell(nb(est), True, raw=True), Cell(nb(ci), True, raw=True)]
        if limits:
            st = states.get(e.name)
            row += [Cell(fmt_number(sc(lo)) if lo is not None else "—", True),
                    Cell(fmt_number(sc(hi)) if hi is not None else "—", True),
                    Cell(f"<b>{html.escape(st)}</b>" if st == spec.OUT else html.escape(st or "no limit"),
                         raw=True)]
        rows.append(row)
        classes.append("out" if limits and states.get(e.name) == spec.OUT else None)
    note = (f"<p class=note>{html.escape(PLUS_MINUS)}. Nominal: the config's value. The config, the limits "
            "file and the JSON are SI; the table shows engineering units."
            + (f" <i>{spec.UNDECIDED}</i>: the estimate is within the limits but its 95 % interval reaches "
               "past one; a longer log or one with less noise decides." if spec.UNDECIDED in states.values()
               else "") + "</p>")
    return table(headers, rows, row_classes=classes) + note


def limits_banner(estimates, limits, judged=True) -> str:
    """One line on the figures against their limits (empty without limits)."""
    if not limits:
        return ""
    if not judged:
        return (f"<p class=warn>The {len(limits)} limited figures are <b>not judged</b> against their "
                "specification limits: the fit is not a usable estimate (above).</p>")
    states = spec.statuses(estimates, limits)
    out = [n for n, s in states.items() if s == spec.OUT]
    if out:
        return (f"<p class=warn><b>Out of specification: {html.escape(', '.join(out))}</b> "
                f"({len(out)} of {len(states)} limited figures): "
                + "; ".join(nb(_beyond(estimates[n].value, limits[n], n)) for n in out) + ".</p>")
    pending = [n for n, s in states.items() if s != spec.IN]
    if pending:
        return (f"<p class=note>No figure out of specification; not decided: "
                f"{html.escape(', '.join(f'{n} ({states[n]})' for n in pending))}.</p>")
    return f"<p class=ok>All {len(states)} limited figures in specification.</p>"


def _beyond(value, limit, name) -> str:
    """'booster.leak 27.0 mg/s > upper limit 25 mg/s'."""
    lo, hi = limit
    f, unit = _shown(name, value, lo, hi)
    bound, sign, which = (hi, ">", "upper") if hi is not None and value > hi else (lo, "<", "lower")
    u = "" if unit in ("–", "?") else f" {unit}"
    return f"{name} {value * f:.4g}{u} {sign} {which} limit {bound * f:.4g}{u}"


def channel_table(fits) -> str:
    """Per channel: fit %, residual RMS and noise sigma in engineering units, RMS / noise."""
    rows = []
    for c, fit in fits.items():
        name, unit, k = CHANNELS[c]
        ratio = fit.rms / fit.noise if fit.noise else float("nan")
        flag = " — the model misses something here" if ratio >= MISSED else ""
        rows.append([Cell(name), Cell(f"{fit.fit_percent:.2f}", True), Cell(nb(f"{fit.rms * k:.4g} {unit}"), True, raw=True),
                     Cell(nb(f"{fit.noise * k:.4g} {unit}"), True, raw=True), Cell(f"{ratio:.2f}{flag}", True)])
    return table(["channel", "fit %", "residual RMS", "noise σ", "RMS / noise σ"], rows) + (
        "<p class=note>fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) (spec §10). Noise σ: the robust sigma of the "
        "channel's first differences. RMS / noise σ near 1: the model explains the channel to its noise; "
        f"{MISSED:g} or more: it misses something there (pumpsim diagnose names what).</p>")


def _draw_channel(top, bottom, t, y, models, noise, channel):
    name, unit, k = CHANNELS[channel]
    few = y.size < 100  # block means: a marker each, drawn over the line
    top.plot(t, y * k, "o" if few else ".", ms=3.5 if few else 2.0, color="0.45", zorder=3, label="measured",
             **({"mfc": "none", "mew": 0.8} if few else {}))
    labels = list(models)
    for j, label in enumerate(labels):
        last = j == len(labels) - 1
        m = np.asarray(models[label][channel], dtype=float)
        style = dict(color="C0", lw=1.4) if last else dict(color=f"C{j + 1}", lw=1.0, ls="--")
        top.plot(t, m * k, label=label, **style)
        r = (y - m) * k
        bottom.plot(t, r, lw=0.9 if last else 0.7, label=f"{label}: RMS {np.sqrt(np.mean(r ** 2)):.3g} {unit}",
                    **({"color": "C0"} if last else {"color": f"C{j + 1}", "ls": "--"}))
    if noise:
        bottom.axhspan(-noise * k, noise * k, color="0.87", zorder=0, label=f"±1 noise σ ({noise * k:.3g} {unit})")
    bottom.axhline(0, color="0.4", lw=0.6)
    if len(labels) == 1:
        r = (y - np.asarray(models[labels[0]][channel], dtype=float)) * k
        bottom.set_title(f"residual: RMS {np.sqrt(np.mean(r ** 2)):.3g} {unit}"
                         + (f"; grey: ±1 noise σ = {noise * k:.3g}" if noise else ""), fontsize=8.5)
    else:
        bottom.legend(fontsize=7, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.32), ncol=1)
    span = np.nanmax(y) / max(np.nanmin(y), 1e-300)
    if channel == "booster_pressure" and np.nanmin(y) > 0 and span > LOG_SCALE_SPAN:
        top.set_yscale("log")  # labelled 5, 10, 20, 50, 100 kPa as read, not powers of ten
        top.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        top.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        top.yaxis.set_minor_formatter(NullFormatter())
    else:
        tidy_axis(top)
    top.set_title(name, fontsize=10)
    top.set_ylabel(f"{name} [{unit}]")
    bottom.set_ylabel(f"residual [{unit}]")
    bottom.set_xlabel("time [s]")
    for a in (top, bottom):
        a.grid(alpha=0.3)
    top.legend(fontsize=7.5, frameon=False, loc="best", markerscale=1 if few else 3)


def channel_figure(time, measured, models, noise=None) -> str:
    """Measured channels (dots) against the model(s) over time, one column per channel (booster
    pressure in kPa absolute, on a log axis when it falls by more than LOG_SCALE_SPAN; current in
    A; speed in rpm), the residual measured − model of each model under it with the ±1 noise σ band.
    time, measured: {channel: samples} (SI); models: {label: {channel: samples}}, the last drawn
    as the result; noise: {channel: sigma} (SI)."""
    chans = [c for c in CHANNELS if c in measured]
    fig, ax = plt.subplots(2, len(chans), figsize=(4.4 * len(chans) + 0.6, 6.4), squeeze=False, sharex="col",
                           gridspec_kw={"height_ratios": [2.2, 1.0]})
    for j, c in enumerate(chans):
        _draw_channel(ax[0, j], ax[1, j], np.asarray(time[c], float), np.asarray(measured[c], float), models,
                      (noise or {}).get(c), c)
        ax[0, j].tick_params(labelbottom=True)
    fig.tight_layout()
    return figure_html(fig)


def effects_figure(rows, unit="noise σ") -> str:
    """Each named effect's residual RMS before and after it is refitted: rows are (name, before,
    after) in `unit` (a bench-log diagnosis: the weighted RMS in noise sigmas)."""
    names = [r[0] for r in rows]
    y = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(8.5, 0.5 * len(rows) + 1.3))
    ax.barh(y - 0.2, [r[1] for r in rows], height=0.38, color="0.7", label="before (the model up to the previous effect)")
    ax.barh(y + 0.2, [r[2] for r in rows], height=0.38, color="C0", label="after refitting the effect")
    for k, (_, before, after) in enumerate(rows):
        ax.text(before, k - 0.2, f" {before:.3g}", va="center", fontsize=8)
        ax.text(after, k + 0.2, f" {after:.3g}", va="center", fontsize=8)
    if unit == "noise σ":
        ax.axvline(1.0, color="k", ls=":", lw=0.8, label="the noise level")
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlabel(f"residual RMS [{unit}]")
    ax.set_xlim(0, 1.15 * max(max(r[1], r[2]) for r in rows))
    ax.legend(fontsize=8, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    return figure_html(fig)


def correlation_html(names, corr) -> str:
    """The correlation matrix of the estimates, |r| above 0.95 in bold."""
    if corr is None or len(names) < 2:
        return ""
    rows = [[Cell(n)] + [Cell(f"<b>{v:+.3f}</b>" if i != j and abs(v) > 0.95 else f"{v:+.3f}", True, raw=True)
                         for j, v in enumerate(r)] for i, (n, r) in enumerate(zip(names, corr))]
    return ("<h3>Correlation of the estimates</h3>" + table([""] + list(names), rows)
            + "<p class=note>Bold: |r| > 0.95, the log tells the pair's combination better than either.</p>")


def verdict_html(fit) -> str:
    """Usable or not and why: convergence, iterations, the weighted residual RMS, the problems."""
    r, problems = fit.result, fit.problems()
    head = "Usable estimate" if not problems else "Not a usable estimate"
    text = (f"<b>{head}.</b> {html.escape(r.method)} {'converged' if r.converged else '<b>did not converge</b>'} "
            f"after {len(r.iterations) - 1} iterations ({html.escape(r.message)}); weighted residual RMS "
            f"{nb(f'{r.rms:.3g} noise σ')} (1: the model explains the log to its noise); "
            f"{r.n_evaluations} model runs, {r.wall_time:.0f} s.")
    items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
    return f"<p class={'ok' if not problems else 'warn'}>{text}</p>" + (f"<ul class=warn>{items}</ul>" if items else "")


def log_rows(log) -> list:
    """What was logged: samples, duration and rate, the supply voltage, the pressure range."""
    t, v, p = log.time, log.voltage, log.booster_pressure
    chans = ", ".join(["time", "voltage", "current", "booster_pressure"] + (["speed"] if log.speed is not None else []))
    return [("file", log.name), ("channels", chans),
            ("samples, duration, rate", f"{log.n:,}, {t[-1] - t[0]:.4g} s, {1 / log.step:.4g} Hz"),
            ("supply voltage: mean (min … max)", f"{np.mean(v):.3g} V ({np.min(v):.3g} … {np.max(v):.3g} V)"),
            ("booster pressure: first → last sample", f"{p[0] / 1e3:.4g} → {p[-1] / 1e3:.4g} kPa abs")]


def bench_log_report(fit, path, title=None, cfg=None, log=None, limits=None, provenance_rows=None) -> None:
    """Write the HTML report of a BenchFit (pumpsim.identification.pumpdown_fit) to `path`.

    cfg: the PumpConfig fitted (its name and the nominal values); log: the BenchLog (what was
    logged); limits: {name: (lower, upper)} in SI (pumpsim.limits); provenance_rows: the rows
    of the provenance block (default: the config and log given, with the fit's compiled kernel)."""
    from ..presentation import provenance

    r = fit.result
    name = cfg.name if cfg is not None else "bench log"
    title = title or f"pumpsim bench-log identification: {name}"
    rows_p = provenance_rows if provenance_rows is not None else provenance(
        cfg, log, kernel_key=(r.provenance or {}).get("kernel_key"))
    nominal, judged = nominal_values(cfg, r.estimates), not fit.problems()
    parts = [f"<h1>{html.escape(title)}</h1>", provenance_line(rows_p), verdict_html(fit),
             limits_banner(r.estimates, limits, judged),
             "<h2>Identified figures</h2>", figures_table(r.estimates, nominal, limits, judged)]
    identified = [n for n, e in r.estimates.items() if e.identifiable and e.value is not None]
    parts.append(correlation_html(identified, r.correlation))
    if fit.notes:
        parts.append("<h3>What this log cannot separate, and what would</h3><ul>"
                     + "".join(f"<li>{html.escape(n)}</li>" for n in fit.notes) + "</ul>")
    blocks = len(fit.time.get("current", [])) < len(fit.time.get("booster_pressure", []))
    parts += ["<h2>Measured and fitted</h2>",
              channel_figure(fit.time, fit.measured, {"fitted model": fit.fitted},
                             {c: f.noise for c, f in fit.channels.items()}),
              "<p class=note>Dots: the log; line: the model with the identified figures, driven by the "
              "logged voltage. Under each channel its residual (measured − model) and the ±1 noise σ band."
              + (" Current and speed are compared as means over blocks of about one revolution: a bench "
                 "samples far below the vane-passing rate, and no model reproduces the ripple's phase "
                 "sample by sample." if blocks else "") + "</p>",
              "<h2>Fit per channel</h2>", channel_table(fit.channels)]
    if log is not None:
        parts += ["<h2>The log</h2>", table(["item", "value"], log_rows(log))]
    parts.append(provenance_html(rows_p))
    write_page(path, title, parts)
