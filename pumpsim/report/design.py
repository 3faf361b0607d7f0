"""Self-contained HTML reports for design reviews (figures embedded as PNG), each opening with
one provenance line and ending with the provenance block (study and base config with their
SHA-256, compiled kernels, pumpsim version, date, command).

Sweep, tolerance study (a random sample: sobol, lhs, random): yield, per-output statistics with
spec limits and Cpk, histograms, a tornado of the largest influences and a scatter matrix.
Sweep, grid (deterministic points): no statistics of a sample -- each output over the swept
quantity, the share of the evaluated designs within the limits, the designs the model could not
evaluate marked and listed. Sensitivity: Sobol' S1/ST (or Morris mu*), one panel per distinct
result, intervals clipped to [0, 1]. Optimisation: the design with units and active bounds,
the constraints with the active ones flagged, convergence of every variable.
"""
from __future__ import annotations

import dataclasses
import html
import math
from pathlib import Path

import numpy as np

from ..presentation import describe, engineering_scale, fmt_number, provenance
from .html import Cell, provenance_html, provenance_line, table, write_page
from . import design_figures as fg
from ..design.outputs import UNITS
from ..design.summary import (
    evaluated,
    flag_counts,
    output_table,
    status_counts,
    within,
    yield_share,
)

CSS_EXTRA = "<style>td.text,th.text{text-align:left}tr.active td{background:#fff4e5}</style>"
ACTIVE_REL = 1e-5  # a value this close to a bound (relative to the range or the bound) is on it


def study_kernels(study, df=None) -> list[str]:
    """Variant and cache key of the compiled kernels a study's designs use (one per vane count
    in the table); never builds one."""
    if study.function is not None or not study.base:
        return []
    try:
        from ..config import config_from_dict
        from ..kernels import load_kernels

        st = config_from_dict(study.base).structure_for(study.model)
        counts = ({int(n) for n in df["rotor.vanes"].dropna()} if df is not None and "rotor.vanes" in df
                  else {st.vanes})
        out = []
        for n in sorted(counts):
            s = dataclasses.replace(st, vanes=n)
            out.append(f"{s.variant}-{load_kernels(s, build=False).key}")
        return out
    except Exception:  # provenance must never break a report  # noqa: BLE001
        return []


def study_provenance(study, df=None) -> list[tuple[str, str]]:
    files = [("study file", study.path)] if Path(study.path).is_file() else []
    if study.config_path:
        files.append(("base config", study.config_path))
    rows = provenance(kernel_key=study_kernels(study, df) or None, files=files)
    rows.insert(len(files) * 2, ("study hash (study + base config)", study.study_hash()))
    if study.function:
        rows.insert(0, ("analytic function", study.function))
    return rows


def _page(path, title, parts, rows) -> None:
    write_page(path, title, [f"<h1>{html.escape(title)}</h1>", _prov_line(rows), CSS_EXTRA, *parts,
                             provenance_html(rows)])


def _prov_line(rows) -> str:
    d = dict(rows)
    study = d.get("study file", "").rsplit("/", 1)[-1]
    sha = d.get("study file SHA-256", "")[:12]
    head = f"study {html.escape(study)} (SHA-256 {sha}…) · " if study else ""
    return provenance_line(rows).replace("<p class=note>", f"<p class=note>{head}", 1)


def _operating_points(df, study) -> str:
    """Speeds, model and (gas outputs) booster pressure of a study, as a phrase."""
    model = ("Model 1 (penalty contact), last of the simulated revolutions" if study.model == "contact"
             else "Model 2, exactly periodic at constant speed")
    text = f"{study.revolution_samples} samples per revolution ({model})"
    if "speed" not in df or study.function is not None:
        return text
    w = df["speed"].to_numpy(dtype=float)
    w = w[np.isfinite(w)]
    if study.booster_pressure is not None and study.speeds is None and df["speed"].nunique() > 1 and w.size:
        speeds = (f"speed set by each design's motor, {w.min():.4g}–{w.max():.4g} rad/s "
                  f"({w.min() * 30 / np.pi:.0f}–{w.max() * 30 / np.pi:.0f} rpm)")
    else:
        u = sorted(set(w.tolist()))
        speeds = (f"{len(u)} speed(s): " + ", ".join(f"{x:.5g} rad/s ({x * 30 / np.pi:.0f} rpm)" for x in u[:6])
                  + (" …" if len(u) > 6 else ""))
    text = f"{speeds}; {text}"
    if study.booster_pressure is not None:
        text += (f"; gas outputs in the gas model's periodic steady state with the booster held at "
                 f"{study.booster_pressure / 1e3:.4g} kPa")
    return text


def _status_section(df, study) -> str:
    bad = df[df["status"] != "ok"]
    if bad.empty:
        return "<p>Every design was evaluated (status ok).</p>"
    keys = [k for k in study.keys if k in df and df[k].nunique() > 1][:3]
    scales = [fg.key_scale(k, df[k].to_numpy(dtype=float)) for k in keys]
    rows = [(int(r["design"]), *[r[k] * f for k, (f, _) in zip(keys, scales)], Cell(str(r["status"]), False))
            for _, r in bad.head(25).iterrows()]
    more = f"<p>… and {len(bad) - 25} more.</p>" if len(bad) > 25 else ""
    return (f"<h2>Designs not ok ({len(bad)}; the first 25)</h2>"
            + table(["design", *[label for _, label in scales], "status"], rows) + more)


def _intro(df, study) -> str:
    counts = status_counts(df)
    return (f"<p>Study <code>{html.escape(study.path)}</code>: sampler {study.sampler}"
            + ("" if study.sampler == "grid" else f", seed {study.seed}")
            + f", {df['design'].nunique()} designs, {_operating_points(df, study)}. Status: "
            + ", ".join(f"{html.escape(k)} {n}" for k, n in counts.items()) + ". Flags: "
            + ", ".join(f"{k} {n}" for k, n in flag_counts(df).items()) + ".</p>")


def _scaled_rows(stats, df, sample: bool):
    """The output table's rows in engineering units; a constant output shows its one value."""
    out = []
    for r in stats:
        o = r["output"]
        f, unit = engineering_scale(r["unit"], df[o].to_numpy(dtype=float)) if r["unit"] else (1.0, "–")
        s = (lambda x, f=f: None if x is None or (isinstance(x, float) and math.isnan(x)) else x * f)
        spec = (f"{r['n_within']} of {r['n_evaluated']}" + (f" ({100 * r['within']:.1f} %)" if sample else "")
                if "within" in r else "")
        if sample:
            spread = "constant" if r["constant"] else s(r["sd"])
            cpk = "—" if r["constant"] or "cpk" not in r else f"{r['cpk']:.2f}"
            out.append((o, unit, r["n"], s(r["mean"]), spread, s(r["min"]), s(r["max"]),
                        s(r["lower"]), s(r["upper"]), spec, cpk if "within" in r else ""))
        else:
            out.append((o, unit, r["n"], s(r["min"]), "constant" if r["constant"] else s(r["max"]),
                        s(r["lower"]), s(r["upper"]), spec))
    return out


def _failed_note(df) -> str:
    kinds = fg.failed_kinds(df)
    n = sum(kinds.values())
    if not n:
        return "every design was evaluated"
    return (f"{n} design(s) not evaluated (" + ", ".join(f"{html.escape(k)} {c}" for k, c in kinds.items())
            + ") are left out of the denominator")


def _grid_parts(df, study) -> list[str]:
    """A grid's page: its points are chosen, not drawn, so no yield, sd, Cpk or histogram."""
    swept = ", ".join(f"{k} ({df[k].nunique()} values)" for k in study.keys)
    k1 = fg.grid_layout(df, study)[0]
    axis = fg.quantity(df, study, k1)[1] if k1 else ""
    parts = [(f"<p>Grid over {html.escape(swept)}: each row is one chosen design, not a draw from a "
             "distribution, so the page shows the outputs over the swept quantity, not statistics "
             f"of a sample. x axis: {html.escape(axis)}.</p>")]
    if study.limits:
        ok = (df["status"] == "ok").to_numpy()
        inside = ok.copy()
        for o, lim in study.limits.items():
            if o in df:
                inside &= within(df[o].to_numpy(dtype=float), lim)
        n_ev = int(evaluated(df).sum())
        parts.append(f"<p><b>Within every limit: {int(inside.sum())} of the {n_ev} evaluated designs</b> "
                     f"(lift-off and paradox designs count as outside); {_failed_note(df)}.</p>")
    stats = output_table(df, study.outputs, study.limits, sample=False)
    parts.append("<h2>Outputs over the grid</h2>" + table(
        ["output", "unit", "designs evaluated", "min", "max", "LSL", "USL", "within limits"],
        _scaled_rows(stats, df, sample=False)))
    parts.append("<h2>Outputs over the swept quantity</h2><p>Outputs constant over the grid are not drawn "
                 "(the table gives their value). Designs the model could not evaluate are crosses at the "
                 "bottom of each panel, in their line's colour.</p>" + fg.grid_plots(df, study))
    return parts


def _sample_parts(df, study) -> list[str]:
    parts = []
    if study.limits:
        y = yield_share(df, study.limits)
        se = math.sqrt(y * (1 - y) / len(df)) if len(df) else math.nan
        parts.append(f"<p><b>Yield {100 * y:.1f} % ± {100 * se:.1f} %</b> (share of the {len(df)} designs "
                     "evaluated and within every spec limit; a design not evaluated, lifting off or meeting "
                     "a paradox counts as a failure; ± one binomial standard error). Per output, "
                     f"<i>in spec</i> counts the evaluated designs only: {_failed_note(df)}.</p>")
    stats = output_table(df, study.outputs, study.limits)
    parts.append("<h2>Outputs</h2><p><i>constant</i>: the spread is below the solver's resolution; the "
                 "value is shown rounded to it.</p>" + table(
                     ["output", "unit", "n", "mean", "sd", "min", "max", "LSL", "USL", "in spec", "Cpk"],
                     _scaled_rows(stats, df, sample=True)))
    parts.append("<h2>Histograms with spec limits</h2>" + fg.histograms(df, study))
    parts.append("<h2>Largest influences (tornado)</h2><p>Bars: change of the output for a ±1 sd "
                 "change of each key, from a linear fit over all designs (R² says how much of the "
                 "spread the fit explains).</p>" + fg.tornado(df, study))
    parts.append("<h2>Keys vs outputs</h2><p>Blue: evaluated designs; red crosses: designs with a "
                 "status other than ok (lift-off, paradox).</p>" + fg.scatter_matrix(df, study))
    return parts


def _sweep_parts(df, study) -> list[str]:
    body = _grid_parts(df, study) if study.sampler == "grid" else _sample_parts(df, study)
    return [_intro(df, study), *body, _status_section(df, study)]


def sweep_report(df, study, path, title=None) -> None:
    title = title or f"pumpsim design study: {study.path}"
    _page(path, title, _sweep_parts(df, study), study_provenance(study, df))


def _index_text(value, conf) -> tuple[str, str]:
    """('0.96', '0.58 … 1.00'): a Sobol' index and its 95 % interval clipped to [0, 1], rounded
    to what the interval resolves."""
    d = fg.sobol_decimals(conf)
    v, lo, hi = fg.clipped(value, conf)
    return f"{v:.{d}f}", f"{lo:.{d}f} … {hi:.{d}f}"


def _sensitivity_table(res) -> str:
    rows = []
    for outs, per in fg.distinct_results(res):
        name = Cell("<br>".join(html.escape(o) for o in outs), False, raw=True)
        for k in res["keys"]:
            r = per[k]
            if res["method"] == "sobol":
                rows.append((name, k, *_index_text(r["S1"], r["S1_conf"]), *_index_text(r["ST"], r["ST_conf"])))
            else:
                d = fg.sobol_decimals(r["mu_star_conf"] / max(abs(r["mu_star"]), 1e-300)) if r["mu_star"] else 3
                rows.append((name, k, *(f"{x:.{d}g}" if x is not None else "—" for x in
                                        (r["mu_star"], r["mu_star_conf"], r["mu"], r["sigma"]))))
            name = ""
    head = (["outputs (identical indices)", "key", "S1", "S1 95 % interval", "ST", "ST 95 % interval"]
            if res["method"] == "sobol" else ["outputs (identical indices)", "key", "mu*", "±95 %", "mu", "sigma"])
    return table(head, rows)


def _unresolved_parts(res) -> list[str]:
    """The warning that the sample is too small for some outputs' Sobol' indices (before the
    figures: the clipped intervals there would hide an index outside [0, 1]); [] when none."""
    found = res.get("_unresolved")
    if not found:
        return []
    head, limit = found["head"], found["limit"]
    rows = "".join(f"<li><b>{html.escape(', '.join(outs))}</b>: {html.escape(why)}</li>" for outs, why in found["groups"])
    bold = ("Sample too small: do not rank keys by these indices yet." if found["inconsistent"]
            else f"Sample too small to read these indices to ±{limit:g}.")
    return [f"<div class=warn><p><b>{bold}</b> {html.escape(head[0].upper() + head[1:])}:</p><ul>{rows}</ul>"
            f"<p>An index should be known to ±{limit:g} (95 %): that tells a key carrying {200 * limit:g} % of the "
            "output's variance from one carrying none. " + html.escape(found["advice"]) + "</p></div>"]


def sensitivity_report(res, study, path, title=None) -> None:
    title = title or f"pumpsim sensitivity: {study.path}"
    groups = fg.distinct_results(res)
    parts = [f"<p>{res['method']} from {res['designs']} designs (base N = {res['samples']}, seed {res['seed']}, "
             f"{res['resamples']} bootstrap resamples). Status: "
             + ", ".join(f"{k} {n}" for k, n in res["status"].items()) + f". {len(res['indices'])} outputs "
             f"carry {len(groups)} distinct result(s): outputs with identical indices share a panel and a "
             "table block.</p>"]
    parts += _unresolved_parts(res)
    if res["method"] == "sobol":
        parts.append("<h2>Sobol' indices</h2><p>S1: share of the output's variance from the key alone; ST: "
                     "with all its interactions. The 95 % bootstrap intervals are clipped to [0, 1], where "
                     "an index lives (an estimate outside is shown at the bound), and every value is "
                     "rounded to the two significant digits of its interval's half-width (at most 3 "
                     "decimals).</p>")
    else:
        parts.append("<h2>Morris screening</h2>")
    parts += [fg.sobol_bars(res), _sensitivity_table(res)]
    for s in res["skipped"]:
        why = ("constant: its spread is below the solver's resolution, no variance to share"
               if s["reason"].startswith("constant") else s["reason"])
        parts.append(f"<p class=warn>Not computed: {html.escape(s['output'])} ({html.escape(why)}).</p>")
    df = res.get("_table")
    if df is not None and len(df):
        parts += ["<h2>The designs evaluated</h2>", *_sweep_parts(df, study)]
    _page(path, title, parts, study_provenance(study, df))


def _at_bound(x, lo, hi) -> str:
    tol = ACTIVE_REL * max(abs(hi - lo), abs(lo), abs(hi), 1e-300)
    return "at lower bound" if abs(x - lo) <= tol else "at upper bound" if abs(x - hi) <= tol else ""


def _design_table(res) -> str:
    o = res["objective"]["minimize"]
    ounit = UNITS.get(o, "")
    rows, cls = [], []
    for k, v in res["design"].items():
        lo, hi = res["bounds"][k]
        f, unit = engineering_scale(describe(k)[1], [lo, hi])
        flag = _at_bound(v, lo, hi)
        rows.append((k, unit, res["start"][k] * f, v * f, lo * f, hi * f, flag or "inside",
                     _gradient_text(res, k, f, unit, ounit)))
        cls.append("active" if flag else None)
    return table(["key", "unit", "start", "found", "lower bound", "upper bound", "bound active",
                  f"d {o} / d key"], rows, row_classes=cls)


def _gradient_text(res, k, f, unit, ounit) -> str:
    """'30.65 W/g': the objective's derivative per shown unit of the key; 0 where its effect over
    the whole range is below the solver's resolution."""
    g = res["gradient"][k]
    if g is None:
        return "—"
    lo, hi = res["bounds"][k]
    if abs(g * (hi - lo)) <= 1e-9 * max(abs(res["objective"]["value"]), 1e-300):
        g = 0.0
    per = f" {ounit}/{unit}" if ounit and unit not in ("–", "?", "-") else (f" {ounit}" if ounit else "")
    return fmt_number(g / f, 4) + per


def _constraint_table(res) -> str:
    rows, cls = [], []
    for k, c in res["constraints"].items():
        vals = [x for x in (c["value"], c["lower"], c["upper"]) if x is not None]
        f, unit = engineering_scale(UNITS.get(k, "-"), vals)
        active = [name for b, name in ((c["lower"], "lower"), (c["upper"], "upper"))
                  if b is not None and abs(c["value"] - b) <= ACTIVE_REL * max(abs(b), 1e-300) + 1e-12]
        rows.append((k, unit, c["value"] * f, None if c["lower"] is None else c["lower"] * f,
                     None if c["upper"] is None else c["upper"] * f, "yes" if c["satisfied"] else "NO",
                     f"active ({active[0]})" if active else "inactive"))
        cls.append("active" if active else None)
    return table(["output", "unit", "value", "lower", "upper", "satisfied", "active"], rows, row_classes=cls)


def _front_parts(res, study) -> list[str]:
    objs = res["objectives"]
    parts = [(f"<p>NSGA-II (pymoo), population {res['population']}, {res['generations']} generations, "
             f"{res['evaluations']} designs evaluated; {len(res['front'])} designs on the front.</p>")]
    if len(objs) >= 2 and res["front"]:
        parts.append(fg.pareto_figure(res))
    if res["front"]:
        cols = [(k, *engineering_scale(describe(k)[1], [f["design"][k] for f in res["front"]])) for k in study.keys]
        outs = [(o, *engineering_scale(UNITS.get(o, "-"), [f["objectives"][o] for f in res["front"]]))
                for o in objs]
        rows = [(*[f["design"][k] * s for k, s, _ in cols], *[f["objectives"][o] * s for o, s, _ in outs])
                for f in res["front"]]
        parts.append(table([f"{k} [{u}]" for k, _, u in cols + outs], rows))
        mid = res["front"][len(res["front"]) // 2]["design"]
        start = {v.key: v.base for v in study.variables if v.base is not None}
        parts.append("<h2>Base design and the middle of the front</h2>"
                     + fg.outlines_figure(study, start, mid, ("base", "middle of the front")))
    return parts


def optimize_report(res, study, path, title=None) -> None:
    title = title or f"pumpsim optimisation: {study.path}"
    rows_p = study_provenance(study)
    if res["method"] == "nsga2":
        _page(path, title, _front_parts(res, study), rows_p)
        return
    o = res["objective"]
    f, unit = engineering_scale(UNITS.get(o["minimize"], "-"), [o["start"], o["value"]])
    n_bounds = sum(bool(_at_bound(v, *res["bounds"][k])) for k, v in res["design"].items())
    parts = [(f"<p>{html.escape(res['method'])}: {html.escape(res['message'])}; minimize {o['minimize']}: "
             f"{o['start'] * f:.6g} → <b>{o['value'] * f:.6g} {unit}</b> after "
             f"{len(res['iterations']) - 1} iterations ({res['evaluations']} evaluations with exact "
             f"kernel gradients). {'Feasible.' if res['feasible'] else '<span class=warn>NOT feasible.</span>'} "
             f"{n_bounds} of {len(res['design'])} variables end on a bound (highlighted): the optimum "
             "lies there, so widening that bound would move it.</p>"),
             "<h2>Design</h2>" + _design_table(res)]
    if res["constraints"]:
        parts.append("<h2>Constraints</h2><p>Active (highlighted): the optimum sits on the limit.</p>"
                     + _constraint_table(res))
    parts.append("<h2>Convergence</h2>" + fg.convergence_figure(res, study))
    parts.append("<h2>Start and found design</h2>" + fg.outlines_figure(study, res["start"], res["design"]))
    _page(path, title, parts, rows_p)
