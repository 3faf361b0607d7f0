"""Figures of the design reports (embedded PNG): every axis in engineering units (mm, µm, kPa,
mN·m) without offset notation, reference lines labelled where they are drawn.

A tolerance (Monte Carlo) study gets histograms with its limits, a tornado of the largest
influences and a scatter matrix of keys vs outputs; a grid gets each output over the swept
quantity (lines, or contours for two continuous keys) with the designs the model could not
evaluate marked; sensitivity gets one panel per distinct set of indices.
"""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import MaxNLocator, ScalarFormatter

from ..model_spec.parameters import alias_targets
from ..presentation import describe, engineering_scale
from .html import figure_html
from ..design.outputs import BOOL_OUTPUTS, UNITS
from ..design.study import base_value, schema_leaf
from ..design.summary import cpk, evaluated, is_constant, resolved_among, status_kind, within

MAX_SCATTER = 2000  # points per scatter panel
MAX_PANELS = 16
LIMIT = "#c0392b"
FAILED = "#c0392b"


def plain(ax, axis="both"):
    """Tick labels without offset or 1e-3 multipliers (the unit carries the scale)."""
    for a in ((ax.xaxis, ax.yaxis) if axis == "both" else (ax.xaxis,) if axis == "x" else (ax.yaxis,)):
        f = ScalarFormatter(useOffset=False)
        f.set_scientific(False)
        a.set_major_formatter(f)


def output_scale(o, values) -> tuple[float, str]:
    """(factor, axis label) of a design output: 'ptp_torque [mN·m]'."""
    unit = UNITS.get(o)
    if not unit:
        return 1.0, o
    f, shown = engineering_scale(unit, values)
    return f, f"{o} [{shown}]"


def key_scale(key, values) -> tuple[float, str]:
    """(factor, axis label) of a varied config key: 'housing.b [mm]'."""
    unit = describe((alias_targets(key) or (key,))[0])[1]  # housing.radius: a semi-axis's
    f, shown = engineering_scale(unit, values)
    return f, (key if shown in ("–", "-", "?", "") else f"{key} [{shown}]")


def quantity(df, study, key):
    """(x values, axis label) of the quantity a study varies through `key`: the ellipse ratio a/b
    when one semi-axis is swept with the other fixed, else the key in engineering units."""
    other = {"housing.b": "housing.a", "housing.a": "housing.b"}.get(key)
    v = df[key].to_numpy(dtype=float)
    if other and other not in study.keys and study.base:
        fixed = base_value(study.base, other)
        if fixed and math.isfinite(fixed):
            a, b = (fixed, v) if key == "housing.b" else (v, fixed)
            return a / b, f"ellipse ratio a/b ({other} = {fixed * 1e3:.4g} mm fixed, {key} varied)"
    f, label = key_scale(key, v)
    return v * f, label


def numeric_outputs(df, study):
    return [o for o in study.outputs if o in df.columns and o not in BOOL_OUTPUTS
            and np.isfinite(df[o].to_numpy(dtype=float)).any()]


def chosen(df, study, n=4):
    """Outputs to show against the inputs: those with limits first, then the varying ones."""
    nums = numeric_outputs(df, study)
    first = [o for o in study.limits if o in nums]
    rest = [o for o in nums if o not in first and not is_constant(df[o].to_numpy(dtype=float), o)]
    return (first + rest)[:n]


def _grid(n, cols=4, w=13, h=2.8):
    rows = max(1, math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(w, h * rows), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    return fig, axes.ravel()


def limit_lines(ax, lim, factor, axis="x"):
    """The spec limits as dashed lines, each named (LSL/USL) inside the axes beside the line."""
    for b, name in zip(lim or (), ("LSL", "USL")):
        if b is None:
            continue
        if axis == "x":
            ax.axvline(b * factor, color=LIMIT, ls="--", lw=1.3)
            lo, hi = ax.get_xlim()
            side = "left" if b * factor < 0.5 * (lo + hi) else "right"  # the label stays inside
            ax.text(b * factor, 0.97, f" {name} ", transform=ax.get_xaxis_transform(), color=LIMIT,
                    fontsize=7, ha=side, va="top")
        else:
            ax.axhline(b * factor, color=LIMIT, ls="--", lw=1.0)
            ax.text(0.99, b * factor, name, transform=ax.get_yaxis_transform(), color=LIMIT, fontsize=7,
                    ha="right", va="bottom")


def laid_out(fig) -> str:
    """A figure whose every label is inside its panels' grid (no figure legend above it) as an
    embedded PNG: tight_layout fits it once, so the PNG needs no tight bbox, and without the
    placeholder layout engine tight_layout leaves behind savefig draws it once, not twice
    (each draw lays out every tick label)."""
    fig.tight_layout()
    fig.set_layout_engine(None)
    return figure_html(fig, tight=False)


def histograms(df, study) -> str:
    """A tolerance study's outputs: histogram with the limits, or 'constant' with its value."""
    outs = numeric_outputs(df, study)[:MAX_PANELS]
    if not outs:
        return ""
    fig, axes = _grid(len(outs), h=2.9)
    ev = evaluated(df)
    for ax, o in zip(axes, outs):
        v = df[o].to_numpy(dtype=float)
        v = v[np.isfinite(v)]
        f, label = output_scale(o, v)
        ax.set_title(label, fontsize=9)
        if is_constant(v, o):  # no spread beyond the solver's resolution: no histogram of round-off
            val = resolved_among(float(np.median(v)), v, o) if v.size else None
            ax.text(0.5, 0.5, "constant\n" + (f"{val * f:.6g} {label.split('[')[-1].rstrip(']')}"
                                              if val is not None else "no value")
                    + "\n(spread below the solver's resolution)", ha="center", va="center",
                    transform=ax.transAxes, fontsize=8.5)
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        # one filled outline per panel, not a patch per bar (same picture, a fraction of the drawing)
        ax.hist(v * f, bins=min(50, max(10, int(np.sqrt(v.size)))), color="#4a7fb5", alpha=0.85,
                histtype="stepfilled")
        lim = study.limits.get(o)
        if lim:
            limit_lines(ax, lim, f)
            inside = within(df[o].to_numpy(dtype=float), lim)[ev]
            ax.set_title(f"{label}\nin spec {100 * inside.mean():.1f} % · Cpk {cpk(v, lim):.2f}", fontsize=9)
        ax.set_ylabel("designs", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        plain(ax, "x")
    return laid_out(fig)


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


def varied_keys(df, study) -> list:
    """The study's keys that take more than one value in the table."""
    return [k for k in study.keys if df[k].nunique() > 1]


def tornado_gap(df, study) -> str | None:
    """Why the tornado cannot be drawn (a sentence), or None when it can."""
    keys = varied_keys(df, study)
    if not keys:
        return "No key varies across the designs (every varied key has one value, e.g. sd = 0): no influences to draw."
    outs = chosen(df, study, 4)
    finite = [int(np.isfinite(df[o].to_numpy(dtype=float)).sum()) for o in outs]
    if not outs or max(finite, default=0) < len(keys) + 2:
        return (f"Too few evaluated designs ({max(finite, default=0)}) for a linear fit of {len(keys)} keys "
                f"(it needs at least {len(keys) + 2}): run more samples to see the influences.")
    return None


def tornado(df, study) -> str:
    gap = tornado_gap(df, study)
    if gap is not None:
        return f"<p class=note>{gap}</p>"
    keys = varied_keys(df, study)
    outs = chosen(df, study, 4)
    fig, axes = plt.subplots(1, len(outs), figsize=(3.3 * len(outs), 0.5 * len(keys) + 1.8), squeeze=False)
    for ax, o in zip(axes[0], outs):
        sw, r2 = regression_swings(df, keys, o)
        if sw is None:
            ax.axis("off")
            continue
        f, label = output_scale(o, df[o].to_numpy(dtype=float))
        order = np.argsort(-np.abs(sw))
        ypos = np.arange(len(keys))
        for y, i in zip(ypos, order):
            s = sw[i] * f
            ax.barh(y, [abs(s)], left=0, color="#c0392b" if s >= 0 else "#2c7fb8", alpha=0.85)
            ax.barh(y, [-abs(s)], left=0, color="#2c7fb8" if s >= 0 else "#c0392b", alpha=0.85)
        ax.set_yticks(ypos, [keys[i] for i in order], fontsize=8)
        ax.invert_yaxis()
        ax.axvline(0, color="k", lw=0.8)
        ax.set_title(f"{o}\n(linear fit R² = {r2:.3f})", fontsize=9)
        ax.set_xlabel(f"change of {label}\nfor ±1 sd of the key (red: key up)", fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(4, symmetric=True))
        plain(ax, "x")
    return laid_out(fig)


def scatter_matrix(df, study) -> str:
    keys = varied_keys(df, study)[:6]
    outs = chosen(df, study, 4)
    if not keys or not outs:
        return ""
    d = df if len(df) <= MAX_SCATTER else df.sample(MAX_SCATTER, random_state=0)
    # a row shares its output's axis, a column its key's: tick labels on the outer panels only
    # (the text layout of every panel's ticks was most of the figure's cost)
    fig, axes = plt.subplots(len(outs), len(keys), figsize=(2.4 * len(keys) + 1, 2.1 * len(outs) + 0.5),
                             squeeze=False, sharex="col", sharey="row")
    ok = (d["status"] == "ok").to_numpy()
    for i, o in enumerate(outs):
        fy, ylabel = output_scale(o, df[o].to_numpy(dtype=float))
        y = d[o].to_numpy(dtype=float) * fy
        for j, k in enumerate(keys):
            ax = axes[i, j]
            fx, xlabel = key_scale(k, df[k].to_numpy(dtype=float))
            x = d[k].to_numpy(dtype=float) * fx
            ax.plot(x[ok], y[ok], ".", ms=2, color="#2c7fb8", alpha=0.6)
            if (~ok).any():
                ax.plot(x[~ok], y[~ok], "x", ms=3, color=FAILED, alpha=0.7)
            limit_lines(ax, study.limits.get(o), fy, axis="y")
            if i == len(outs) - 1:
                ax.set_xlabel(xlabel, fontsize=7.5)
            if j == 0:
                ax.set_ylabel(ylabel, fontsize=7.5)
            ax.tick_params(labelsize=6.5)
            ax.xaxis.set_major_locator(MaxNLocator(3))
            ax.yaxis.set_major_locator(MaxNLocator(4))
            plain(ax)
            ax.label_outer()
    return laid_out(fig)


def grid_layout(df, study):
    """(x key, grouping key or None, contour?) of a grid: lines over a continuous key, one per
    value of a discrete one (a vane count); contours for two continuous keys of 3+ values."""
    keys = varied_keys(df, study)
    if not keys:
        return None, None, False
    k1, k2 = keys[0], (keys[1] if len(keys) > 1 else None)
    discrete = [k for k in keys if schema_leaf(k) == "int"]
    if k2 is not None and k1 in discrete:
        k1, k2 = k2, k1
    contour = (k2 is not None and len(keys) == 2 and not discrete and df[k1].nunique() >= 3
               and df[k2].nunique() >= 3)
    return k1, k2, contour


def grid_plots(df, study) -> str:
    """Each output that changes over the grid against the swept quantity; the designs the model
    could not evaluate as red crosses on the x axis (lines) or in the plane (contours)."""
    k1, k2, contour = grid_layout(df, study)
    outs = [o for o in numeric_outputs(df, study) if not is_constant(df[o].to_numpy(dtype=float), o)]
    if k1 is None or not outs:
        return ""
    fig, axes = _grid(len(outs[:MAX_PANELS]), h=3.0)
    x, xlabel = quantity(df, study, k1)
    ev = evaluated(df)
    for ax, o in zip(axes, outs[:MAX_PANELS]):
        f, label = output_scale(o, df[o].to_numpy(dtype=float))
        y = df[o].to_numpy(dtype=float) * f
        if contour:
            _contour(fig, ax, df, study, x, y, k2, ev)
        else:
            _lines(ax, df, x, y, k2, ev)
            limit_lines(ax, study.limits.get(o), f, axis="y")
        ax.set_title(label, fontsize=9)
        ax.set_xlabel(xlabel.split(" (")[0], fontsize=8)
        ax.tick_params(labelsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(5))
        plain(ax)
        ax.grid(alpha=0.3)
    handles, names = axes[0].get_legend_handles_labels()
    if handles:  # one legend for every panel, above them: it covers no curve
        fig.legend(handles, names, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=min(len(names), 7),
                   fontsize=8, frameon=False)
    fig.tight_layout()
    return figure_html(fig)


def _lines(ax, df, x, y, k2, ev):
    """One line per value of k2 over the evaluated designs; a failed design is a cross on the x
    axis in its line's colour (a line does not silently end)."""
    groups = [(None, np.ones(len(df), bool))] if k2 is None else [
        (val, (df[k2] == val).to_numpy()) for val in sorted(df[k2].unique())]
    if k2 is not None and _coincide(x, y, [rows & ev for _, rows in groups]):
        ax.text(0.02, 0.97, f"the same for every {k2}", transform=ax.transAxes, fontsize=7.5, va="top")
    for n, (val, rows) in enumerate(groups):
        color = f"C{n % 10}"
        good = rows & ev
        order = np.argsort(x[good])
        name = "evaluated designs" if val is None else f"{k2} = {val:g}"
        ax.plot(x[good][order], y[good][order], "o-", ms=3, color=color, label=name)
        bad = rows & ~ev
        if bad.any():  # stacked a little per line so that every line's failures stay visible
            ax.plot(x[bad], np.full(bad.sum(), 0.03 + 0.035 * n), "x", ms=6, mew=1.6, color=color, clip_on=False,
                    transform=ax.get_xaxis_transform(),
                    label=None if val is not None else "not evaluated (see the status table)")
    if k2 is not None and (~ev).any():
        ax.plot([], [], "x", color="0.3", mew=1.6, label="× at the bottom: not evaluated (status table)")


def _coincide(x, y, masks, rtol=1e-9) -> bool:
    """Whether the lines of every group lie on each other (only the last drawn would show)."""
    curves = [(x[m][np.argsort(x[m])], y[m][np.argsort(x[m])]) for m in masks if m.any()]
    scale = max((np.nanmax(np.abs(c[1])) for c in curves), default=0.0)
    return len(curves) > 1 and all(
        c[0].shape == curves[0][0].shape and np.allclose(c[0], curves[0][0])
        and np.nanmax(np.abs(c[1] - curves[0][1])) <= rtol * scale for c in curves[1:])


def _contour(fig, ax, df, study, x, y, k2, ev):
    """Filled contours of an output over two continuous keys; failed designs as red crosses."""
    yv, ylabel = quantity(df, study, k2)
    xs, ys = np.unique(x[ev]), np.unique(yv[ev])
    Z = np.full((ys.size, xs.size), np.nan)
    Z[np.searchsorted(ys, yv[ev]), np.searchsorted(xs, x[ev])] = y[ev]
    if np.isfinite(Z).sum() >= 4 and np.nanstd(Z) > 0:
        cs = ax.contourf(xs, ys, np.ma.masked_invalid(Z), levels=12, cmap="viridis")
        fig.colorbar(cs, ax=ax).ax.tick_params(labelsize=6)
    ax.plot(x[ev], yv[ev], "k.", ms=2, label="evaluated designs")
    if (~ev).any():
        ax.plot(x[~ev], yv[~ev], "x", color=FAILED, ms=5, mew=1.5, label="not evaluated (status table)")
    ax.set_ylabel(ylabel.split(" (")[0], fontsize=8)


def failed_kinds(df) -> dict:
    """Counts of the statuses without output values ('geometry': 10)."""
    kinds = status_kind(df)[~evaluated(df)]
    return {k: int(n) for k, n in kinds.value_counts().items()}


def sobol_decimals(conf) -> int:
    """Decimals that show a Sobol' index to its 95 % half-width's two significant digits (1 to 3:
    an index below 0.001 is zero for a design decision)."""
    if conf is None or not math.isfinite(conf) or conf <= 0:
        return 3
    return int(min(3, max(1, 1 - math.floor(math.log10(conf)))))


def clipped(value, conf) -> tuple[float, float, float]:
    """(estimate, lower, upper) of an index and its 95 % interval, clipped to [0, 1] where a
    Sobol' index lives (bootstrap intervals of a near-0 or near-1 index cross the bounds)."""
    v = 0.0 if value is None or not math.isfinite(value) else float(value)
    c = 0.0 if conf is None or not math.isfinite(conf) else float(conf)
    return min(max(v, 0.0), 1.0), min(max(v - c, 0.0), 1.0), min(max(v + c, 0.0), 1.0)


def distinct_results(res, tol=5e-4) -> list[tuple[list, dict]]:
    """Outputs grouped by identical indices ([outputs], their indices): outputs proportional to
    each other (mean torque and friction power at one speed) carry one result, drawn once.
    Identical: every index and interval agrees within tol (below the 3rd decimal shown; relative
    to the largest for Morris' mu*, which carries the output's unit)."""
    names = (("S1", "ST", "S1_conf", "ST_conf") if res["method"] == "sobol"
             else ("mu_star", "mu", "sigma", "mu_star_conf"))
    keys = res["keys"]
    groups = []
    for o, per in res["indices"].items():
        vec = np.array([per[k][n] or 0.0 for k in keys for n in names], dtype=float)
        for outs, ref, _ in groups:
            scale = 1.0 if res["method"] == "sobol" else max(np.abs(ref).max(), 1e-300)
            if vec.shape == ref.shape and np.all(np.abs(vec - ref) <= tol * scale):
                outs.append(o)
                break
        else:
            groups.append(([o], vec, per))
    return [(outs, per) for outs, _, per in groups]


def sobol_bars(res) -> str:
    """One panel per distinct result: S1 and ST with their 95 % intervals clipped to [0, 1]
    (Morris: mu* with its interval)."""
    groups = distinct_results(res)[:MAX_PANELS]
    if not groups:
        return ""
    keys = res["keys"]
    cols = min(3, len(groups))
    fig, axes = _grid(len(groups), cols=cols, w=4.6 * cols, h=0.42 * len(keys) + 1.9)
    y = np.arange(len(keys))
    sobol = res["method"] == "sobol"
    series = ((("S1", "S1_conf", "#2c7fb8", "S1 (first order)"), ("ST", "ST_conf", "#c0392b", "ST (total)"))
              if sobol else (("mu_star", "mu_star_conf", "#2c7fb8", "mu*"),))
    for ax, (outs, per) in zip(axes, groups):
        for off, (name, conf, color, label) in zip((-0.2, 0.2) if sobol else (0.0,), series):
            if sobol:
                est = np.array([clipped(per[k][name], per[k][conf]) for k in keys])
            else:
                est = np.array([(v, max(v - c, 0.0), v + c) for v, c in
                                ((per[k][name] or 0.0, per[k][conf] or 0.0) for k in keys)])
            ax.barh(y + off, est[:, 0], 0.38 if sobol else 0.6, color=color, alpha=0.85, label=label,
                    xerr=np.vstack([est[:, 0] - est[:, 1], est[:, 2] - est[:, 0]]),
                    error_kw={"lw": 1, "capsize": 2})
        if sobol:
            ax.set_xlim(0, 1.02)
        ax.set_xlabel("Sobol' index, 95 % interval clipped to [0, 1]" if sobol
                      else "Morris mu* (output per unit quantile), 95 % interval", fontsize=8)
        ax.set_yticks(y, keys, fontsize=8)
        ax.invert_yaxis()
        ax.set_title("\n".join(outs), fontsize=8.5)
        ax.grid(alpha=0.3, axis="x")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    return figure_html(fig)


def outline(study, values):
    """Housing outline, rotor circle and vanes at the start angle of the design `values`."""
    from ..geometry import housing_samples, vane_positions
    from ..kernels import load_kernels
    from ..design.evaluate import prepare

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


def outlines_figure(study, base_values, found_values, names=("start", "found")) -> str:
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for vals, color, name in ((base_values, "#7f7f7f", names[0]), (found_values, "#c0392b", names[1])):
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
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    ax.grid(alpha=0.3)
    ax.set_title("housing, rotor (dotted) and vanes at the start angle", fontsize=9)
    fig.tight_layout()
    return figure_html(fig)


def convergence_figure(res, study) -> str:
    """Objective, constraint violation and every variable over the iterations, each variable with
    its bounds (labelled) in engineering units."""
    its = res["iterations"]
    keys = list(res["design"])
    fig, axes = _grid(2 + len(keys), cols=4, h=2.9)
    n = np.arange(len(its))
    o = res["objective"]["minimize"]
    f, label = output_scale(o, [h["objective"] for h in its])
    axes[0].plot(n, [h["objective"] * f for h in its], "o-")
    axes[0].set_title(f"objective {label}", fontsize=9)
    axes[1].semilogy(n, [max(h["violation"], 1e-16) for h in its], "o-", color="#c0392b")
    axes[1].set_title("largest constraint violation (scaled; 1e-16: none)", fontsize=9)
    for ax, k in zip(axes[2:], keys):
        lo, hi = res["bounds"][k]
        fk, klabel = key_scale(k, [lo, hi])
        ax.plot(n, [h["design"][k] * fk for h in its], "o-", color="#2c7fb8")
        for b, name in ((lo, "lower bound"), (hi, "upper bound")):
            ax.axhline(b * fk, color="0.4", ls="--", lw=0.9)
            ax.text(0.01, b * fk, name, transform=ax.get_yaxis_transform(), fontsize=6.5, color="0.3",
                    ha="left", va="bottom" if name == "lower bound" else "top")
        ax.set_title(klabel, fontsize=9)
        plain(ax, "y")
    for ax in axes[:2 + len(keys)]:
        ax.set_xlabel("iteration", fontsize=8)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    return figure_html(fig)


def pareto_figure(res) -> str:
    objs = res["objectives"][:2]
    F = np.array([[f["objectives"][o] for o in objs] for f in res["front"]])
    (fx, lx), (fy, ly) = (output_scale(o, F[:, i]) for i, o in enumerate(objs))
    order = np.argsort(F[:, 0])
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(F[order, 0] * fx, F[order, 1] * fy, "o-", color="#c0392b", ms=4)
    ax.set_xlabel(lx)
    ax.set_ylabel(ly)
    plain(ax)
    ax.grid(alpha=0.3)
    ax.set_title("Pareto front (non-dominated designs)")
    fig.tight_layout()
    return figure_html(fig)
