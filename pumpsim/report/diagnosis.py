"""The diagnosis report: it draws a `pumpsim.diagnosis.DiagnosisResult` and nothing else -- every
figure and statistic it shows (BIC, amplitudes and phases, drift) is one the result carries."""
from __future__ import annotations

import html
import math
import re

import matplotlib.pyplot as plt
import numpy as np

from ..presentation import PLUS_MINUS, describe, display_scale, fmt_estimate, parameter_text, provenance
from .html import Cell, figure_html, nb, provenance_html, provenance_line, table, write_page
from .identification import interval_warning, param_row, residual_figures, torque_overlay
from .simulation import tidy_axis

RANKING_SHOWN = 8  # candidates shown per screen; the full ranking is one click away

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
    runs_p, lb_p = final["runs_p_value"], final["ljung_box_p_value"]
    white = out.residual_tests_white  # the page says this and, where they differ, the verdict's view
    rms_final, rms_base = f"{final['rms']:.4g} N·m", f"{out.baseline['rms']:.4g} N·m"
    verdict += (f" Final residual RMS {nb(rms_final)} (baseline {nb(rms_base)}), "
                f"{'white' if white else '<b>not white</b>'} at {100 * out.white_alpha:g} % "
                f"(runs p = {runs_p:.3g}, Ljung–Box p = {lb_p:.3g})"
                + ("; what remains is below the relevance bar (see the verdict)."
                   if not white and final["residual_white"] else "."))
    stalled = out.unconverged()  # the figures of a fit that did not converge are not its minimum
    clear = final["residual_white"] and not out.unexplained and not stalled
    parts.append(f"<p class={'ok' if clear else 'warn'}>{verdict}</p>")
    parts += [f"<p class=warn><b>{html.escape(s[0].upper() + s[1:])}</b>: its figures are not the fit's minimum and "
              "the verdict may be wrong -- check the config's values against the pump (the vane COF first) and "
              "diagnose again; the notes say how the fit stopped.</p>" for s in stalled]
    if out.unexplained:
        parts.append("<p class=warn><b>Unexplained residual</b>: no candidate effect explains it. Where: "
                     + ", ".join(nb(_where_text(w)) for w in out.unexplained_where) + ".</p>")
    parts.append(f"<p>Verdict: {html.escape(out.verdict)}.</p>")
    for a, b in out.confounded:
        parts.append(f"<p class=warn>Confounded: {html.escape(a)} and {html.escape(b)} have nearly collinear "
                     f"effects on this data, which cannot tell them apart: {html.escape(a)} is not named "
                     "(see the notes).</p>")
    for a, b in getattr(out, "hidden_in_baseline", ()):
        parts.append(f"<p class=note>{html.escape(a)} would hide in the fitted {html.escape(b)} on this "
                     f"data: a {html.escape(a)} the size of the noise cannot be told from a different "
                     f"{html.escape(b)} (see the notes for what would separate them).</p>")
    last_res = out.history[-1].result if out.history else None
    parts.append(interval_warning(white, final["runs_p_value"], final["ljung_box_p_value"],
                                  None if last_res is None else last_res.residual))
    parts += [_steps_table(out), _final_table(out)]
    if out.screens:
        parts.append("<h2>Candidate ranking</h2><p class=note>Each screen tests every candidate of the library "
                     "by a score (Lagrange-multiplier) test at the current fit, no refit; the significant ones "
                     "(p below the Bonferroni level) are ranked by p-value; the best few and every significant "
                     "out-of-round order are refitted and compared by BIC. ΔBIC &lt; 0 favours the candidate.</p>")
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

