"""Self-contained HTML reports for identification and diagnosis (figures embedded as base64 PNG,
no external files, scripts or fonts: they open anywhere, including headless browsers).

Every report starts with a provenance block (data files and their SHA-256, config, date, pumpsim
version, compiled kernel), shows every parameter with its unit, and uses "±" for one standard error
exactly as the terminal output does (`presentation.PLUS_MINUS`). When the residual is not white the
intervals are flagged as optimistic, with the AR(1) inflation factor that would widen them.

The diagnosis report draws a `pumpsim.diagnosis.DiagnosisResult` and nothing else: every figure
and statistic it shows (BIC, amplitudes and phases) is one the result carries.
"""
from __future__ import annotations

import base64
import html
import io
import math
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from .diagnostics import order_spectrum, synchronous_average  # noqa: E402
from .io import write_text  # noqa: E402
from .plotting import wrapped_angle, tidy_axis  # noqa: E402
from .presentation import (OPTIMISTIC, PLUS_MINUS, describe, display_scale, fmt_estimate,  # noqa: E402
                           fmt_interval, fmt_number, parameter_text, provenance)

CSS = ("body{font-family:DejaVu Sans,Arial,sans-serif;max-width:1150px;margin:1.5em auto;color:#222;"
       "line-height:1.35}h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}"
       "table{border-collapse:collapse;margin:.4em 0}td,th{border:1px solid #bbb;padding:3px 8px}"
       "th{background:#eee;text-align:left}td.n{text-align:right;white-space:nowrap;"
       "font-variant-numeric:tabular-nums}td.t{text-align:left}span.nb{white-space:nowrap}"
       "img{max-width:100%}.warn{color:#8a3b00;background:#fff4e5;border-left:4px solid #e08a00;"
       "padding:.4em .8em}.ok{background:#eef7ee;border-left:4px solid #3a3;padding:.4em .8em}"
       "table.prov td{font-size:.85em;font-family:monospace}.note{font-size:.88em;color:#555}"
       "tr.chosen td{background:#eef7ee;font-weight:bold}")
RPM = 60 / (2 * math.pi)
RANKING_SHOWN = 8  # candidates shown per screen; the full ranking is one click away


def figure_html(fig) -> str:
    """The figure as an embedded PNG; bbox 'tight' so no axis label is clipped."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=96, bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)
    return f'<img alt="figure" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


class Cell:
    """A table cell: numbers right-aligned and never wrapped, text left-aligned."""

    def __init__(self, text, numeric=None, raw=False):
        self.text = text if raw else html.escape(str(text))
        self.numeric = numeric


def table(headers, rows, cls=None, row_classes=None) -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in headers)
    body = []
    for k, r in enumerate(rows):
        cells = []
        for c in r:
            if not isinstance(c, Cell):
                c = Cell(fmt_number(c) if isinstance(c, (int, float)) or c is None else c,
                         numeric=isinstance(c, (int, float)) or c is None)
            cells.append(f"<td class={'n' if c.numeric else 't'}>{c.text}</td>")
        rc = f" class={row_classes[k]}" if row_classes and row_classes[k] else ""
        body.append(f"<tr{rc}>" + "".join(cells) + "</tr>")
    c = f" class={cls}" if cls else ""
    return f"<table{c}><tr>{h}</tr>{''.join(body)}</table>"


def nb(text) -> str:
    """Escaped text that does not wrap (a number with its unit)."""
    return f"<span class=nb>{html.escape(text)}</span>"


def provenance_html(rows) -> str:
    return "<h2>Provenance</h2>" + table(["item", "value"], [(k, Cell(v, False)) for k, v in rows], cls="prov")


def provenance_of(res, cfg=None, data=None) -> list:
    """Provenance rows from the config and data given, else from a result's own `provenance`
    dict ({config, data: [{name, sha256}], kernel_key}) when it carries one."""
    own = getattr(res, "provenance", None)
    if cfg is not None or data is not None or not isinstance(own, dict) or not own:
        return provenance(cfg, data)
    rows = []
    for i, d in enumerate(own.get("data", [])):
        tag = "data file" if len(own["data"]) == 1 else f"data file {i + 1}"
        rows += [(tag, str(d.get("name"))), (f"{tag} SHA-256", str(d.get("sha256")))]
    rows.append(("config", str(own.get("config"))))
    return rows + [r for r in provenance(kernel_key=own.get("kernel_key")) if r[0] != "config"]


def provenance_line(rows) -> str:
    """One line under the title: what was fitted, when, with which version (details at the end)."""
    d = dict(rows)
    data = [v for k, v in rows if k.startswith("data file") and not k.endswith(("SHA-256", "samples"))]
    shas = [v[:12] for k, v in rows if k.startswith("data file") and k.endswith("SHA-256")]
    bits = [f"data {', '.join(html.escape(x.rsplit('/', 1)[-1]) for x in data)}"
            + (f" (SHA-256 {', '.join(shas)}…)" if shas else "") if data else "",
            f"config {html.escape(d['config'].split(' (')[0])}" if "config" in d else "",
            f"pumpsim {html.escape(d.get('pumpsim version', '?'))}", html.escape(d.get("date (UTC)", "")) + " UTC"]
    return f"<p class=note>{' · '.join(b for b in bits if b)} — provenance at the end.</p>"


def write_page(path, title, parts) -> None:
    page = (f"<!doctype html><html lang=en><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{CSS}</style></head><body>{''.join(parts)}</body></html>")
    write_text(path, page)


# -- shared pieces -------------------------------------------------------------------------------

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


# -- diagnosis -------------------------------------------------------------------------------------

_NUMBER_WITH_ERROR = re.compile(r"[-+]?[0-9][0-9.]*(?:e[-+]?[0-9]+)? ± [0-9.]+(?:e[-+]?[0-9]+)?"
                                r"(?: (?:rad|µm|mm|m|N·m|N·s/m|rad/s|s|kg|% of ω0))?(?: \([^)]*\))?")


def _nb_list(items) -> str:
    """Items separated by '; ', each free to wrap between words but never inside 'value ± s.e. unit'."""
    out = []
    for x in items:
        text, pos, parts = str(x), 0, []
        for m in _NUMBER_WITH_ERROR.finditer(text):
            parts.append(html.escape(text[pos:m.start()]) + nb(m.group(0)))
            pos = m.end()
        parts.append(html.escape(text[pos:]))
        out.append("".join(parts))
    return "; ".join(out)


def diagnosis_report(out, path, title="pumpsim diagnosis", cfg=None, data=None, provenance_rows=None) -> None:
    """Write the HTML report of a DiagnosisResult `out` to `path` (cfg and data: for the provenance
    block and the joint fit's measurements)."""
    rows_p = provenance_rows if provenance_rows is not None else provenance(cfg, data)
    final = out.final
    parts = [f"<h1>{html.escape(title)}</h1>", provenance_line(rows_p)]
    named = out.effects
    verdict = (f"Effects named: <b>{html.escape(', '.join(named))}</b>." if named else
               "No effect of the library is named.")
    white = final["residual_white"]
    rms_final, rms_base = f"{final['rms']:.4g} N·m", f"{out.baseline['rms']:.4g} N·m"
    verdict += (f" Final residual RMS {nb(rms_final)} (baseline {nb(rms_base)}), "
                f"{'white' if white else '<b>not white</b>'} at 5 % "
                f"(runs p = {final['runs_p_value']:.3g}, Ljung–Box p = {final['ljung_box_p_value']:.3g}).")
    parts.append(f"<p class={'ok' if white and not out.unexplained else 'warn'}>{verdict}</p>")
    if out.unexplained:
        parts.append("<p class=warn><b>Unexplained residual</b>: no candidate effect explains it. Where: "
                     + ", ".join(nb(_where_text(w)) for w in out.unexplained_where) + ".</p>")
    parts.append(f"<p>Verdict: {html.escape(out.verdict)}.</p>")
    for a, b in out.confounded:
        parts.append(f"<p class=warn>Confounded: {html.escape(a)} and {html.escape(b)} have nearly collinear "
                     f"effects on this data, which cannot tell them apart: {html.escape(a)} is not named "
                     "(see the notes).</p>")
    last_res = out.history[-1].result if out.history else None
    parts.append(interval_warning(white, final["runs_p_value"], final["ljung_box_p_value"],
                                  None if last_res is None else last_res.residual))
    parts += [_steps_table(out), _final_table(out)]
    if out.screens:
        parts.append("<h2>Candidate ranking</h2><p class=note>Each screen tests every candidate of the library "
                     "by a score (Lagrange-multiplier) test at the current fit, no refit; the significant ones "
                     "(p below the Bonferroni level) are ranked by p-value, the best few refitted and compared "
                     "by BIC. ΔBIC &lt; 0 favours the candidate.</p>")
        parts += [_ranking_table(i, sc) for i, sc in enumerate(out.screens)]
    parts += [f"<h2>{html.escape(d['text'])}</h2>" + _drift_figure(d) for d in out.drift]
    if out.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in out.notes) + "</ul>")
    parts.append(f"<p class=note>Method: {html.escape(out.method)}.</p>")
    for h in out.history:
        parts.append(f"<h2>Model after: {html.escape(h.label)} (RMS {h.result.rms:.4g} N·m)</h2>")
        parts.append(torque_overlay(h.result, data, label=f"model ({h.label})", show_initial=False))
        parts.append(residual_figures(h.result, data))
    parts.append(provenance_html(rows_p))
    write_page(path, title, parts)


BIC_NOTE = ("BIC = n ln(RSS/n) + k ln n of the prewhitened residual, as each step's acceptance test computes "
            "it: both models on the samples both keep, prewhitened with the AR(1) coefficient of the residual "
            "the step starts from -- so a step's 'before' is not the row above's 'after'.")


def _steps_table(out) -> str:
    base = out.baseline
    headers = ["step", "RMS [N·m]", "RMS change", "score-test p", "BIC before", "BIC after", "ΔBIC",
               "parameters (± s.e.)"]
    base_items = [parameter_text(n, v["value"], v["stderr"]) for n, v in base["params"].items()]
    rows = [[Cell("baseline"), Cell(f"{base['rms']:.5g}", True), Cell("", True), Cell("", True), Cell("", True),
             Cell("", True), Cell("", True), Cell(_nb_list(base_items), raw=True)]]
    for s in out.steps:
        change = (s.rms_after - s.rms_before) / s.rms_before * 100 if s.rms_before else float("nan")
        rows.append([Cell(s.effect.name), Cell(f"{s.rms_after:.5g}", True), Cell(f"{change:+.1f} %", True),
                     Cell(f"{s.p_value:.2g}", True), Cell(f"{s.bic_before:.1f}", True),
                     Cell(f"{s.bic_after:.1f}", True), Cell(f"{s.delta_bic:+.1f}", True),
                     Cell(_nb_list(s.parameter_texts()), raw=True)])
    return ("<h2>Steps</h2>" + table(headers, rows)
            + f"<p class=note>{html.escape(BIC_NOTE)} {html.escape(PLUS_MINUS)}.</p>")


def _final_table(out) -> str:
    """Every parameter of the final model with its unit; out-of-round and ripple coefficients as
    amplitude and phase (the result's, at the final fit)."""
    harmonics = out.final_harmonics
    last = out.history[-1].result if out.history else None
    skip = {n for s in out.steps if s.effect.polar is not None
            for n, v in s.params.items() if isinstance(v, dict) and n not in ("amplitude", "phase")}
    rows = []
    for n, v in out.final["params"].items():
        if n in skip:
            continue
        e = last.estimates.get(n) if last is not None else None
        row = param_row(n, v["value"], v["stderr"], getattr(e, "lower95", None), getattr(e, "upper95", None),
                        None, harmonics)
        nd = v.get("not_determined")
        if v["value"] is None and nd and nd.get("estimate") is not None:  # an estimate smaller than its s.e.
            f, _ = display_scale(describe(n, harmonics)[1], nd["estimate"])
            se = None if nd.get("stderr") is None else nd["stderr"] * f
            row[4] = Cell(nb(f"not determined ({fmt_estimate(nd['estimate'] * f, se)})"), True, raw=True)
        rows.append(row)
    for p in out.final_polar:
        form, name = p.effect.polar, f"{p.effect.polar.title} k = {p.order}"
        rows.append(_polar_row(name, form.amplitude_meaning, p.amplitude, form.scale, form.unit))
        rows.append(_polar_row(name, form.phase_meaning, p.phase, 1.0, "rad"))
    return ("<h2>Final model parameters</h2>" + table(["parameter", "meaning", "unit", "estimate ± s.e."],
                                                      [[r[0], r[1], r[2], r[4]] for r in rows])
            + f"<p class=note>{html.escape(PLUS_MINUS)}.</p>")


def _polar_row(name, meaning, v, f, unit):
    extra = f" ({math.degrees(v['value']):.4g}°)" if unit == "rad" else ""
    return [Cell(name), Cell(meaning), Cell(unit), None,
            Cell(nb(fmt_estimate(v["value"] * f, v["stderr"] * f) + extra), True, raw=True)]


def _where_text(w) -> str:
    if "order" in w:
        return f"shaft order {w['order']:.3f} ({w['frequency']:.1f} Hz)"
    if "angle_deg" in w:
        return f"rotor angle {w['angle_deg']:.1f}°"
    return ", ".join(f"{k} {v}" for k, v in w.items())


# ranking columns: header, key, format; a column is shown when some row has the key
RANKING_COLUMNS = [("score-test p", "p_value", ".2g"), ("one-step RMS [N·m]", "one_step_rms", ".5g"),
                   ("one-step BIC", "one_step_bic", ".1f")]


def _ranking_table(i, screen) -> str:
    cands = [r.to_json() for r in screen.candidates]
    cols = [c for c in RANKING_COLUMNS if any(r.get(c[1]) is not None for r in cands)]
    headers = ["rank", "candidate"] + [c[0] for c in cols[:1]] + ["significant"] + [c[0] for c in cols[1:]] \
        + ["collinear with"]
    rows, classes = [], []
    for k, r in enumerate(cands, 1):
        vals = [Cell("—" if r.get(key) is None else format(r[key], f), True) for _, key, f in cols]
        rows.append([Cell(str(k), True), Cell(r["candidate"])] + vals[:1]
                    + [Cell("yes" if r["significant"] else "no")] + vals[1:]
                    + [Cell(r["collinear_with"] or "")])
        classes.append("chosen" if r["candidate"] == screen.chosen else None)
    shown = RANKING_SHOWN
    visible = table(headers, rows[:shown], row_classes=classes[:shown])
    if len(rows) > shown:
        visible += (f"<details><summary>all {len(rows)} candidates</summary>"
                    + table(headers, rows, row_classes=classes) + "</details>")
    head = (f"<h3>Screen {i + 1} (after {html.escape(screen.after)}): "
            f"{'chose ' + html.escape(screen.chosen) if screen.chosen else 'nothing accepted'}"
            + (f"; Bonferroni level {screen.alpha:.2g}" if screen.alpha else "") + "</h3>")
    return head + visible


def _drift_figure(d) -> str:
    """A drifting parameter's segment fits (value +- 1 s.e.) and their straight line over time."""
    seg = d["segments"]
    t = np.array([x["time"] for x in seg])
    v = np.array([x["value"] for x in seg])
    e = np.array([x["stderr"] or 0.0 for x in seg])
    fig, ax = plt.subplots(figsize=(6.4, 2.8))
    ax.errorbar(t, v, yerr=e, fmt="o", capsize=3, label="segment fits (± 1 s.e.)")
    ax.plot([0, d["over"]], d["line"], "-", label="trend")  # the drift test's own line
    ax.set_xlabel("time [s]")
    ax.set_ylabel(d["parameter"])
    ax.legend(loc="best", fontsize=8)
    tidy_axis(ax)
    return figure_html(fig)
