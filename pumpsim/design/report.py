"""Self-contained HTML reports for design reviews (figures embedded as PNG).

Sweep: status and yield, per-output statistics with spec limits and Cpk, histograms with the
limits, a tornado of the largest influences (linear-regression swing of a +-1 sd change of each
key, with the fit's R²), a scatter matrix of keys vs the chosen outputs, and for a grid the
outputs over the swept keys (lines, or contours for two keys with 3+ values each).
Sensitivity: Sobol' S1/ST bars with their 95 % intervals (or Morris mu*). Optimisation:
convergence, the design found next to the start, both housing outlines.
"""
from __future__ import annotations

import html
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from ..report import figure_html, table, write_page  # noqa: E402
from .outputs import BOOL_OUTPUTS, UNITS  # noqa: E402
from .summary import (cpk, flag_counts, is_constant, output_table, status_counts, within,  # noqa: E402
                      yield_share)

MAX_SCATTER = 2000  # points per scatter panel
CSS_EXTRA = "<style>td.text,th.text{text-align:left}</style>"
MAX_PANELS = 16


def _label(o):
    u = UNITS.get(o)
    return f"{o} [{u}]" if u else o


def _numeric_outputs(df, study):
    return [o for o in study.outputs if o in df.columns and o not in BOOL_OUTPUTS
            and np.isfinite(df[o].to_numpy(dtype=float)).any()]


def _chosen(df, study, n=4):
    """Outputs to show against the inputs: those with limits first, then the spec's leading ones."""
    nums = _numeric_outputs(df, study)
    first = [o for o in study.limits if o in nums]
    varying = [o for o in nums if o not in first and np.nanstd(df[o].to_numpy(dtype=float)) > 0]
    return (first + varying)[:n]


def histograms(df, study) -> str:
    outs = [o for o in _numeric_outputs(df, study)][:MAX_PANELS]
    if not outs:
        return ""
    cols = 4
    rows = math.ceil(len(outs) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(13, 2.6 * rows), squeeze=False)
    for ax, o in zip(axes.ravel(), outs):
        v = df[o].to_numpy(dtype=float)
        v = v[np.isfinite(v)]
        lim = study.limits.get(o)
        title = o
        if is_constant(v, o):
            # no spread beyond rounding: say so instead of a histogram of round-off
            ax.text(0.5, 0.5, "constant\n" + (f"{np.median(v):.6g}" if v.size else "no value"),
                    ha="center", va="center", transform=ax.transAxes, fontsize=10)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(title, fontsize=9)
            continue
        ax.hist(v, bins=min(50, max(10, int(np.sqrt(v.size)))), color="#4a7fb5", alpha=0.85)
        if lim:
            for b, name in zip(lim, ("LSL", "USL")):
                if b is not None:
                    ax.axvline(b, color="#c0392b", ls="--", lw=1.5)
                    ax.annotate(name, (b, 1), xycoords=("data", "axes fraction"), color="#c0392b",
                                fontsize=8, ha="center", va="bottom")
            inside = within(df[o].to_numpy(dtype=float), lim).mean()
            title += f"\nin spec {100 * inside:.1f} %, Cpk {cpk(v, lim):.2f}"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(_label(o), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4), useOffset=False)
    for ax in axes.ravel()[len(outs):]:
        ax.axis("off")
    fig.tight_layout()
    return figure_html(fig)


def regression_swings(df, keys, output):
    """(swing per key for a +-1 sd change, R²) of a linear fit output ~ keys over the finite rows."""
    X = df[keys].to_numpy(dtype=float)
    y = df[output].to_numpy(dtype=float)
    ok = np.isfinite(y) & np.isfinite(X).all(axis=1)
    X, y = X[ok], y[ok]
    sd = X.std(axis=0)
    use = sd > 0
    if y.size < use.sum() + 2 or not use.any():
        return None, math.nan
    Z = (X[:, use] - X[:, use].mean(axis=0)) / sd[use]
    A = np.column_stack([np.ones(len(y)), Z])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    r2 = 1 - resid.var() / y.var() if y.var() > 0 else math.nan
    sw = np.zeros(len(keys))
    sw[use] = coef[1:]
    return sw, r2


def tornado(df, study) -> str:
    keys = [k for k in study.keys if df[k].nunique() > 1]
    outs = _chosen(df, study, 4)
    if not keys or not outs:
        return ""
    fig, axes = plt.subplots(1, len(outs), figsize=(3.4 * len(outs) + 1, 0.5 * len(keys) + 1.6), squeeze=False)
    for ax, o in zip(axes[0], outs):
        sw, r2 = regression_swings(df, keys, o)
        if sw is None:
            ax.axis("off")
            continue
        order = np.argsort(np.abs(sw))
        ypos = np.arange(len(keys))
        ax.barh(ypos, np.abs(sw[order]), color="#c0392b", alpha=0.8, label="+1 sd")
        ax.barh(ypos, -np.abs(sw[order]), color="#2c7fb8", alpha=0.8, label="−1 sd")
        for y, s in zip(ypos, sw[order]):
            ax.annotate("+" if s >= 0 else "−", (0, y), ha="center", va="center", fontsize=8, color="w")
        ax.set_yticks(ypos, [keys[i] for i in order], fontsize=8)
        ax.axvline(0, color="k", lw=0.8)
        ax.set_title(f"{o}\n(linear fit R² = {r2:.3f})", fontsize=9)
        ax.set_xlabel(f"change of {_label(o)}\nfor ±1 sd of the key", fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4), useOffset=False)
    fig.tight_layout()
    return figure_html(fig)


def scatter_matrix(df, study) -> str:
    keys = [k for k in study.keys if df[k].nunique() > 1][:6]
    outs = _chosen(df, study, 4)
    if not keys or not outs:
        return ""
    d = df if len(df) <= MAX_SCATTER else df.sample(MAX_SCATTER, random_state=0)
    fig, axes = plt.subplots(len(outs), len(keys), figsize=(2.3 * len(keys) + 1, 2.0 * len(outs) + 0.5),
                             squeeze=False)
    ok = (d["status"] == "ok").to_numpy()
    for i, o in enumerate(outs):
        for j, k in enumerate(keys):
            ax = axes[i, j]
            ax.plot(d[k][ok], d[o][ok], ".", ms=2, color="#2c7fb8", alpha=0.6)
            if (~ok).any():
                ax.plot(d[k][~ok], d[o][~ok], "x", ms=3, color="#c0392b", alpha=0.7)
            lim = study.limits.get(o)
            for b in (lim or ()):
                if b is not None:
                    ax.axhline(b, color="#c0392b", ls="--", lw=1)
            if i == len(outs) - 1:
                ax.set_xlabel(k, fontsize=8)
            if j == 0:
                ax.set_ylabel(o, fontsize=8)
            ax.tick_params(labelsize=6)
            ax.ticklabel_format(style="sci", scilimits=(-3, 4), useOffset=False)
            ax.xaxis.set_major_locator(MaxNLocator(3))
    fig.tight_layout()
    return figure_html(fig)


def grid_plots(df, study) -> str:
    keys = [k for k in study.keys if df[k].nunique() > 1]
    outs = _numeric_outputs(df, study)
    outs = [o for o in outs if np.nanstd(df[o].to_numpy(dtype=float)) > 0][:8] or outs[:4]
    if not keys or not outs:
        return ""
    d = df[df["status"].str.split(":").str[0].isin(["ok", "lift_off", "paradox"])]
    cols = 4
    rows = math.ceil(len(outs) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(13, 2.9 * rows), squeeze=False)
    k1 = keys[0]
    k2 = keys[1] if len(keys) > 1 else None
    from .study import schema_leaf

    discrete = [k for k in keys if schema_leaf(k) == "int"]
    if discrete and k2 is not None and k1 in discrete:  # lines over the continuous key, one per count
        k1, k2 = k2, k1
    contour = (k2 is not None and len(keys) == 2 and not discrete and d[k1].nunique() >= 3
               and d[k2].nunique() >= 3)
    for ax, o in zip(axes.ravel(), outs):
        if contour:
            pv = d.groupby([k2, k1])[o].mean().unstack()
            Xg, Yg = np.meshgrid(pv.columns.to_numpy(), pv.index.to_numpy())
            Z = pv.to_numpy(dtype=float)
            if np.isfinite(Z).sum() >= 4 and np.nanstd(Z) > 0:
                cs = ax.contourf(Xg, Yg, np.ma.masked_invalid(Z), levels=12, cmap="viridis")
                fig.colorbar(cs, ax=ax).ax.tick_params(labelsize=6)
            ax.plot(Xg[np.isfinite(Z)], Yg[np.isfinite(Z)], "k.", ms=2)
            ax.set_xlabel(k1, fontsize=8)
            ax.set_ylabel(k2, fontsize=8)
        else:
            groups = [(None, d)] if k2 is None else list(d.groupby(k2))
            for val, g in groups:
                g = g.groupby(k1)[o].mean()
                ax.plot(g.index, g.to_numpy(), "o-", ms=3, label=None if val is None else f"{k2} = {val:g}")
            if k2 is not None:
                ax.legend(fontsize=6)
            ax.set_xlabel(k1, fontsize=8)
            for b in study.limits.get(o, ()):
                if b is not None:
                    ax.axhline(b, color="#c0392b", ls="--", lw=1)
        ax.set_title(_label(o), fontsize=9)
        ax.tick_params(labelsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(outs):]:
        ax.axis("off")
    fig.tight_layout()
    return figure_html(fig)


def _status_section(df) -> str:
    bad = df[df["status"] != "ok"]
    if bad.empty:
        return "<p>Every design was evaluated (status ok).</p>"
    rows = "".join(f"<tr><td>{int(r.design)}</td><td class=text>{html.escape(str(r.status))}</td></tr>"
                   for r in bad.head(25).itertuples())
    more = f"<p>… and {len(bad) - 25} more.</p>" if len(bad) > 25 else ""
    return (f"<h3>Designs not ok (first 25)</h3>{CSS_EXTRA}<table><tr><th>design</th>"
            f"<th class=text>status</th></tr>{rows}</table>" + more)


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
        speeds = f"{len(u)} speed(s): " + ", ".join(f"{x:.5g}" for x in u[:6]) + (" …" if len(u) > 6 else "") + " rad/s"
    text = f"{speeds}; {text}"
    if study.booster_pressure is not None:
        text += (f"; gas outputs in the gas model's periodic steady state with the booster held at "
                 f"{study.booster_pressure / 1e3:.4g} kPa (spec §8)")
    return text


def _sweep_parts(df, study):
    counts = status_counts(df)
    parts = [f"<p>Study <code>{html.escape(study.path)}</code>: sampler {study.sampler}, seed {study.seed}, "
             f"{df['design'].nunique()} designs, {_operating_points(df, study)}. Status: "
             + ", ".join(f"{html.escape(k)} {n}" for k, n in counts.items()) + ". Flags: "
             + ", ".join(f"{k} {n}" for k, n in flag_counts(df).items()) + ".</p>"]
    if study.limits:
        parts.append(f"<p><b>Yield {100 * yield_share(df, study.limits):.2f} %</b> (evaluated and within every "
                     "spec limit; a design not evaluated counts as a failure).</p>")
    stats = output_table(df, study.outputs, study.limits)
    parts.append("<h2>Outputs</h2>" + table(
        ["output", "unit", "n", "mean", "sd", "min", "max", "LSL", "USL", "in spec", "Cpk"],
        [(r["output"], r["unit"], r["n"], r["mean"], r["sd"], r["min"], r["max"],
          r["lower"], r["upper"], f"{100 * r['within']:.2f} %" if "within" in r else "",
          r.get("cpk", "")) for r in stats]))
    parts.append("<h2>Histograms with spec limits</h2>" + histograms(df, study))
    if study.sampler == "grid":
        parts.append("<h2>Outputs over the swept keys</h2>" + grid_plots(df, study))
    else:
        parts.append("<h2>Largest influences (tornado)</h2><p>Bars: change of the output for a ±1 sd "
                     "change of each key, from a linear fit over all designs (R² says how much of the "
                     "spread the fit explains).</p>" + tornado(df, study))
    if study.sampler != "grid":
        parts.append("<h2>Keys vs outputs</h2><p>Blue: evaluated designs; red crosses: designs with a "
                     "status other than ok (lift-off, paradox).</p>" + scatter_matrix(df, study))
    parts.append(_status_section(df))
    return parts


def sweep_report(df, study, path, title=None) -> None:
    title = title or f"pumpsim design study: {study.path}"
    write_page(path, title, [f"<h1>{html.escape(title)}</h1>", *_sweep_parts(df, study)])


def sobol_bars(res) -> str:
    outs = list(res["indices"])[:MAX_PANELS]
    if not outs:
        return ""
    cols = min(3, len(outs))
    rows = math.ceil(len(outs) / cols)
    keys = res["keys"]
    fig, axes = plt.subplots(rows, cols, figsize=(4.4 * cols, 0.35 * len(keys) * rows + 2.2 * rows), squeeze=False)
    y = np.arange(len(keys))
    for ax, o in zip(axes.ravel(), outs):
        per = res["indices"][o]
        if res["method"] == "sobol":
            for off, (name, conf, color) in zip((-0.2, 0.2), (("S1", "S1_conf", "#2c7fb8"), ("ST", "ST_conf", "#c0392b"))):
                v = [per[k][name] or 0.0 for k in keys]
                e = [per[k][conf] or 0.0 for k in keys]
                ax.barh(y + off, v, 0.38, xerr=e, color=color, alpha=0.85, label=name,
                        error_kw={"lw": 1, "capsize": 2})
            ax.set_xlim(min(0, ax.get_xlim()[0]), max(1.0, ax.get_xlim()[1]))
            ax.set_xlabel("Sobol' index (95 % interval)", fontsize=8)
        else:
            v = [per[k]["mu_star"] for k in keys]
            e = [per[k]["mu_star_conf"] for k in keys]
            ax.barh(y, v, 0.6, xerr=e, color="#2c7fb8", label="mu*", error_kw={"lw": 1, "capsize": 2})
            ax.set_xlabel("Morris mu* (per unit quantile)", fontsize=8)
        ax.set_yticks(y, keys, fontsize=8)
        ax.invert_yaxis()
        ax.set_title(o, fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3, axis="x")
    for ax in axes.ravel()[len(outs):]:
        ax.axis("off")
    fig.tight_layout()
    return figure_html(fig)


def sensitivity_report(res, study, path, title=None) -> None:
    title = title or f"pumpsim sensitivity: {study.path}"
    parts = [f"<h1>{html.escape(title)}</h1>",
             f"<p>{res['method']} from {res['designs']} designs (base N = {res['samples']}, seed {res['seed']}, "
             f"{res['resamples']} bootstrap resamples). Status: "
             + ", ".join(f"{k} {n}" for k, n in res["status"].items()) + ".</p>"]
    if res["method"] == "sobol":
        rows = [(o, k, r["S1"], r["S1_conf"], r["ST"], r["ST_conf"]) for o, per in res["indices"].items()
                for k, r in per.items()]
        parts.append("<h2>Sobol' indices</h2>" + sobol_bars(res)
                     + table(["output", "key", "S1", "±95 %", "ST", "±95 %"], rows))
    else:
        rows = [(o, k, r["mu_star"], r["mu_star_conf"], r["mu"], r["sigma"]) for o, per in res["indices"].items()
                for k, r in per.items()]
        parts.append("<h2>Morris screening</h2>" + sobol_bars(res)
                     + table(["output", "key", "mu*", "±95 %", "mu", "sigma"], rows))
    for s in res["skipped"]:
        parts.append(f"<p class=warn>Not computed: {html.escape(s['output'])} ({html.escape(s['reason'])}).</p>")
    df = res.get("_table")
    if df is not None and len(df):
        parts += ["<h2>The designs evaluated</h2>", *_sweep_parts(df, study)[1:]]
    write_page(path, title, parts)


def outline(study, values):
    """Housing outline, rotor circle and vanes at the start angle of the design `values`."""
    from ..geometry import housing_samples, vane_positions
    from ..kernels import load_kernels
    from .evaluate import prepare

    pr = prepare(study, values)
    if pr.status != "ok":
        return None
    kern = load_kernels(pr.cfg.structure_for("constrained"))
    _, pts, _ = housing_samples(kern, pr.p, 720)
    s, _, _ = vane_positions(kern, pr.p, [pr.cfg.angle])
    v = pr.values
    N = pr.cfg.vanes
    vanes = []
    for i in range(N):
        phi = v["rotor.first_slot_angle"] + 2 * math.pi * i / N + pr.cfg.angle
        u = np.array([math.cos(phi + v["rotor.slot_tilt"]), math.sin(phi + v["rotor.slot_tilt"])])
        ob = v["rotor.slot_radius"] * np.array([math.cos(phi), math.sin(phi)])
        a = ob + s[i, 0] * u
        vanes.append((a, a + v["vane.length"] * u))
    return {"housing": pts, "rotor": v["rotor.radius"], "vanes": vanes}


def outlines_figure(study, base_values, found_values) -> str:
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for vals, color, name in ((base_values, "#7f7f7f", "start"), (found_values, "#c0392b", "found")):
        g = outline(study, vals)
        if g is None:
            continue
        h = g["housing"] * 1e3
        ax.plot(np.append(h[0], h[0][0]), np.append(h[1], h[1][0]), color=color, lw=1.6, label=f"housing ({name})")
        t = np.linspace(0, 2 * math.pi, 200)
        ax.plot(g["rotor"] * 1e3 * np.cos(t), g["rotor"] * 1e3 * np.sin(t), color=color, lw=0.8, ls=":")
        for a, b in g["vanes"]:
            ax.plot([a[0] * 1e3, b[0] * 1e3], [a[1] * 1e3, b[1] * 1e3], color=color, lw=3, alpha=0.6,
                    solid_capstyle="butt")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    ax.set_title("housing, rotor (dotted) and vanes at the start angle", fontsize=9)
    fig.tight_layout()
    return figure_html(fig)


def optimize_report(res, study, path, title=None) -> None:
    title = title or f"pumpsim optimisation: {study.path}"
    parts = [f"<h1>{html.escape(title)}</h1>"]
    if res["method"] == "nsga2":
        objs = res["objectives"]
        parts.append(f"<p>NSGA-II (pymoo), population {res['population']}, {res['generations']} generations, "
                     f"{res['evaluations']} designs evaluated; {len(res['front'])} designs on the front.</p>")
        if len(objs) >= 2 and res["front"]:
            fig, ax = plt.subplots(figsize=(6, 4.5))
            F = np.array([[f["objectives"][o] for o in objs[:2]] for f in res["front"]])
            ax.plot(F[:, 0], F[:, 1], "o-", color="#c0392b", ms=4)
            ax.set_xlabel(_label(objs[0]))
            ax.set_ylabel(_label(objs[1]))
            ax.grid(alpha=0.3)
            ax.set_title("Pareto front")
            fig.tight_layout()
            parts.append(figure_html(fig))
        rows = [(*[f["design"][k] for k in study.keys], *[f["objectives"][o] for o in objs]) for f in res["front"]]
        parts.append(table([*study.keys, *objs], rows))
        if res["front"]:
            mid = res["front"][len(res["front"]) // 2]["design"]
            start = {v.key: v.base for v in study.variables if v.base is not None}
            parts.append("<h2>Base design and the middle of the front</h2>" + outlines_figure(study, start, mid))
        write_page(path, title, parts)
        return
    o = res["objective"]
    parts.append(f"<p>{html.escape(res['method'])}: {html.escape(res['message'])}; minimize {o['minimize']}: "
                 f"{o['start']:.6g} → <b>{o['value']:.6g}</b> {UNITS.get(o['minimize'], '')} after "
                 f"{len(res['iterations']) - 1} iterations ({res['evaluations']} evaluations with exact "
                 f"kernel gradients). {'Feasible.' if res['feasible'] else '<span class=warn>NOT feasible.</span>'}</p>")
    rows = [(k, res["start"][k], v, *res["bounds"][k], res["gradient"][k]) for k, v in res["design"].items()]
    parts.append("<h2>Design</h2>" + table(["key", "start", "found", "lower bound", "upper bound",
                                           f"d {o['minimize']} / d key"], rows))
    if res["constraints"]:
        parts.append("<h3>Constraints</h3>" + table(
            ["output", "value", "lower", "upper", "satisfied"],
            [(k, c["value"], c["lower"], c["upper"], "yes" if c["satisfied"] else "NO")
             for k, c in res["constraints"].items()]))
    its = res["iterations"]
    fig, ax = plt.subplots(1, 2 + min(len(study.keys), 2), figsize=(13, 3.2))
    n = np.arange(len(its))
    ax[0].plot(n, [h["objective"] for h in its], "o-")
    ax[0].set_title(_label(o["minimize"]), fontsize=9)
    ax[1].semilogy(n, [max(h["violation"], 1e-16) for h in its], "o-", color="#c0392b")
    ax[1].set_title("largest constraint violation (scaled)", fontsize=9)
    for a, k in zip(ax[2:], study.keys):
        a.plot(n, [h["design"][k] for h in its], "o-", color="#2c7fb8")
        a.set_title(k, fontsize=9)
    for a in ax:
        a.set_xlabel("iteration")
        a.grid(alpha=0.3)
        a.tick_params(labelsize=7)
    fig.tight_layout()
    parts.append("<h2>Convergence</h2>" + figure_html(fig))
    parts.append("<h2>Start and found design</h2>" + outlines_figure(study, res["start"], res["design"]))
    write_page(path, title, parts)
