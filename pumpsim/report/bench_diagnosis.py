"""The report of a bench-log diagnosis (spec §10), read in a minute: the verdict (the effects
named with their sizes and intervals, the pairs the log cannot tell apart with the experiment
that would, where an unexplained residual lies), the effects table, each effect's residual RMS
before and after, the measured channels against the baseline and the final model, the notes and
the provenance. It draws a `BenchDiagnosis` and nothing else: every number it shows is one the
result carries."""
from __future__ import annotations

import html

from ..presentation import describe, engineering_scale, fmt_estimate, fmt_interval, kernel_key_of, provenance
from .benchlog import CHANNELS, channel_figure, effects_figure
from .html import Cell, nb, provenance_html, provenance_line, table, write_page

Z95 = 1.96  # the 95 % interval of an estimate: value ± Z95 s.e. (the JSON carries value and s.e.)


def _param(name, v) -> tuple[str, str, str]:
    """(unit shown, 'value ± s.e.', '95 % interval') of one {value, stderr} entry, in engineering
    units; an estimate larger than its standard error is no result and says so."""
    value, se = v.get("value"), v.get("stderr")
    shown = v.get("not_determined", {}).get("estimate") if value is None else value
    f, unit = engineering_scale(describe(name)[1], [shown] if shown is not None else [])
    if value is None:
        return unit, "not determined" + (f" ({shown * f:.3g})" if shown is not None else ""), "—"
    se_f = None if se is None else se * f
    ci = "—" if se is None else fmt_interval((value - Z95 * se) * f, (value + Z95 * se) * f, se_f)
    return unit, fmt_estimate(value * f, se_f), ci


def _named_text(step) -> str:
    """'valve_late: valve.cracking 12.1 ± 0.4 kPa (95 %: 11.3 … 12.9), change +10.1 kPa; size 3.2 noise σ'."""
    name = step.effect.param
    v = step.params.get(name, {})
    unit, est, ci = _param(name, v)
    f, _ = engineering_scale(describe(name)[1], [v.get("value") or 0.0])
    change = step.params.get("change")
    bits = [f"{name} {est} {unit} (95 %: {ci})"]
    if change is not None and v.get("value") is not None:
        bits.append(f"change {change * f:+.3g} {unit}")
    bits.append(f"size {step.size:.3g} noise σ")
    return (f"<b>{html.escape(step.effect.name)}</b> ({html.escape(step.effect.description)}): "
            + ", ".join(nb(b) for b in bits))


def _where_text(w) -> str:
    name, unit, k = CHANNELS.get(w["channel"], (w["channel"], w["unit"], 1.0))
    return (f"in the {name} at t {w['time'][0]:.3g} … {w['time'][1]:.3g} s (booster pressure "
            f"{w['pressure'][0] / 1e3:.4g} … {w['pressure'][1] / 1e3:.4g} kPa), mean residual "
            f"{w['mean_residual'] * k:+.3g} {unit.removesuffix(' abs')}")  # a difference: no 'abs'


def _p(p) -> str:
    return "< 1e-16" if p < 1e-16 else f"{p:.2g}"  # below double precision's resolution of a p-value


def _separations(out) -> dict:
    """{(first, second): the experiment that separates them}, as the step log records it."""
    return {frozenset((n.first, n.second)): n.how for n in out.log
            if all(hasattr(n, k) for k in ("first", "second", "how"))}


def verdict_html(out) -> str:
    """The banner: what is named, what is confounded and how to separate it, what is unexplained
    and where, the final RMS and the detectors."""
    stalled = out.unconverged()
    clear = not out.unexplained and not out.confounded and not stalled
    f = out.final
    base_rms, final_rms = f"{out.baseline['rms']:.3g}", f"{f['rms']:.3g} noise σ"
    head = (f"<b>Verdict: {html.escape(out.verdict)}.</b> Residual RMS {nb(base_rms)} "
            f"(baseline) → {nb(final_rms)} (final; 1: the model explains the log to its "
            f"noise); detectors p: runs {_p(f['runs_p_value'])}, Ljung–Box {_p(f['ljung_box_p_value'])}, "
            f"noise level {_p(f['noise_level_p_value'])}"
            + (f", mean level {_p(f['mean_level_p_value'])}" if "mean_level_p_value" in f else "") + ".")
    items = [f"Named: {_named_text(s)}" for s in out.steps] or ["No effect of the library is named."]
    if out.withdrawn:
        items.append("<b>Withdrawn</b>: the search named " + html.escape(", ".join(s.effect.name for s in out.withdrawn))
                     + ", but the model with them is not consistent over the log (its parameters differ between "
                     "the log's parts): the model cannot describe this log; see the notes.")
    items += [f"<b>{html.escape(p[0].upper() + p[1:])}</b>: the verdict may be wrong; see the notes." for p in stalled]
    how = _separations(out)
    for a, b in out.confounded:
        sep = how.get(frozenset((a, b)), "a second experiment")
        items.append(f"<b>Confounded: {html.escape(a)} ~ {html.escape(b)}</b>: this log cannot tell them "
                     f"apart, neither is named; to separate them: {html.escape(sep)}.")
    if out.unexplained:
        items.append("<b>Unexplained residual</b> (no effect of the library explains it)"
                     + (": " + "; ".join(nb(_where_text(w)) for w in out.unexplained_where)
                        if out.unexplained_where else "") + ".")
    return (f"<div class={'ok' if clear else 'warn'}><p>{head}</p><ul>"
            + "".join(f"<li>{x}</li>" for x in items) + "</ul></div>")


def _fit_rows(label, params: dict, rms: float) -> list:
    rows = []
    for n, v in params.items():
        unit, est, ci = _param(n, v)
        rows.append([Cell(label), Cell(n), Cell(unit), Cell(nb(est), True, raw=True), Cell(nb(ci), True, raw=True),
                     Cell("", True), Cell(f"{rms:.4g}", True)] + [Cell("", True)] * 4)
    return rows


def effects_table(out) -> str:
    """The baseline fit, each named effect (its parameter as the final model holds it), the RMS it
    left and its tests, and the final model's other figures: a named effect refits the vane COF, so
    the baseline's is not the pump's."""
    headers = ["step", "parameter", "unit", "estimate ± s.e.", "95 % interval", "RMS before", "RMS after",
               "size", "score p", "LR p", "BIC before → after"]
    rows = _fit_rows("baseline", out.baseline["params"], out.baseline["rms"])
    final = out.final.get("params", {}) if out.steps else {}
    for s in out.steps:
        unit, est, ci = _param(s.effect.param, final.get(s.effect.param, s.params.get(s.effect.param, {})))
        rows.append([Cell(s.effect.name), Cell(s.effect.param), Cell(unit), Cell(nb(est), True, raw=True),
                     Cell(nb(ci), True, raw=True), Cell(f"{s.rms_before:.4g}", True), Cell(f"{s.rms_after:.4g}", True),
                     Cell(f"{s.size:.3g}", True), Cell(_p(s.p_value), True), Cell(_p(s.lr_p_value), True),
                     Cell(nb(f"{s.bic_before:.1f} → {s.bic_after:.1f}"), True, raw=True)])
    named = {s.effect.param for s in out.steps}
    rows += _fit_rows(f"final (with {', '.join(s.effect.name for s in out.steps)})",
                      {n: v for n, v in final.items() if n not in named}, out.final.get("rms", float("nan")))
    return (table(headers, rows) + "<p class=note>RMS and size in noise σ (each channel over its own noise "
            "sigma). Size: the RMS of the model change the effect made. Score p: its screen's score test; "
            f"LR p: the likelihood-ratio test of its refit. ± one standard error; 95 % interval: estimate ± {Z95} "
            "s.e.</p>")


def _channels_html(out) -> str:
    models = {}
    if out.history:
        base = out.history[0]
        fitted = ", ".join(base.params) or "nothing"
        models[f"baseline (config, {fitted} fitted)"] = base.channels
        if len(out.history) > 1:
            after = ", ".join(h.label for h in out.history[1:])
            label = (f"withdrawn (with {after}: not consistent over the log)" if out.withdrawn else
                     f"final (after {after})")
            models[label] = out.history[-1].channels
    if not models or not out.measured:
        return "<p class=note>The result carries no channels to draw.</p>"
    blocks = any(len(out.times.get(c, ())) < len(out.times.get("booster_pressure", ())) for c in out.times)
    styles = (" (dashed: the baseline; solid: the model with the withdrawn effects)" if out.withdrawn else
              " (dashed: the baseline; solid: the final model)" if len(models) > 1 else
              " (no effect named: the baseline is the final model)")
    return (channel_figure(out.times, out.measured, models, out.noise or None)
            + "<p class=note>Dots: the log; lines: the model, driven by the logged voltage" + styles + ". "
            "Under each channel the residual measured − model and the ±1 noise σ band." + (" Current and speed are compared as means over blocks of about one "
                                      "revolution, as the diagnosis compares them." if blocks else "") + "</p>")


def _ranking_html(out) -> str:
    if not out.ranking:
        return ""
    rows = [[Cell(r.get("effect", "")), Cell(f"{r['score_p_value']:.2g}" if r.get("score_p_value") is not None
                                            else "—", True), Cell("yes" if r.get("significant") else "no")]
            for r in out.ranking]
    return ("<details><summary>The last screen: every candidate's score test</summary>"
            + table(["candidate", "score-test p", "significant"], rows) + "</details>")


def bench_diagnosis_report(out, path, title=None, cfg=None, log=None, provenance_rows=None) -> None:
    """Write the HTML report of a BenchDiagnosis `out` to `path`. cfg, log: the PumpConfig and the
    BenchLog diagnosed (for the title and the provenance block); provenance_rows: its rows instead."""
    name = cfg.name if cfg is not None else "bench log"
    title = title or f"pumpsim bench-log diagnosis: {name}"
    rows_p = provenance_rows if provenance_rows is not None else provenance(
        cfg, log, kernel_key=kernel_key_of(cfg, "pneumatic") if cfg is not None else None)
    parts = [f"<h1>{html.escape(title)}</h1>", provenance_line(rows_p), verdict_html(out),
             "<h2>Effects</h2>", effects_table(out)]
    if out.steps:
        parts += ["<h2>Residual RMS before and after each named effect</h2>",
                  effects_figure([(s.effect.name, s.rms_before, s.rms_after) for s in out.steps])]
    parts += ["<h2>Measured and fitted</h2>", _channels_html(out), _ranking_html(out)]
    if out.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in out.notes) + "</ul>")
    budget = out.budget or {}
    parts.append(f"<p class=note>Method: {html.escape(out.method)}. {out.runs} model runs, {out.wall_time:.0f} s"
                 + ("; the time budget was reached: " + html.escape(", ".join(budget.get("cut", [])))
                    if budget.get("bound") else "") + ".</p>")
    parts.append(provenance_html(rows_p))
    write_page(path, title, parts)
