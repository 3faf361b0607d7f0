"""Self-contained HTML reports (figures embedded as base64 PNG)."""
from __future__ import annotations

import base64
import html
import io
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .diagnostics import order_spectrum, synchronous_average  # noqa: E402
from .io import write_text  # noqa: E402

CSS = ("body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}"
       "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
       "th{background:#eee}img{max-width:100%}.warn{color:#a40}")


def figure_html(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return f'<img src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


def residual_figures(t, residual, speed, angle, title="residual"):
    """Residual in time, in shaft orders and as an angle-domain average (one figure)."""
    fig, ax = plt.subplots(1, 3, figsize=(13, 3))
    ax[0].plot(t, residual, lw=0.6)
    ax[0].set_xlabel("time [s]")
    ax[0].set_ylabel(f"{title} [N·m]")
    sp = order_spectrum(residual, t[1] - t[0], speed)
    ax[1].plot(sp["order"], sp["amplitude"], lw=0.8)
    for pk in sp["peaks"][:5]:
        ax[1].annotate(f"{pk['order']:.2f}", (pk["order"], pk["amplitude"]), fontsize=7)
    ax[1].set_xlim(0, min(40, sp["order"].max()))
    ax[1].set_xlabel("shaft order")
    ax[1].set_ylabel("amplitude [N·m]")
    sa = synchronous_average(residual, angle)
    ax[2].plot(np.degrees(sa["angle"]), sa["average"])
    ax[2].set_xlabel("rotor angle [deg]")
    ax[2].set_ylabel("angle-domain average [N·m]")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    return figure_html(fig)


def table(headers, rows) -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in headers)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _fmt(x):
    if isinstance(x, float):
        return "—" if math.isnan(x) else f"{x:.6g}"
    return "—" if x is None else str(x)


def identification_report(res, path, title="pumpsim identification") -> None:
    parts = [f"<h1>{html.escape(title)}</h1>",
             f"<p>{html.escape(res.method)}: {'converged' if res.converged else 'not converged'} "
             f"({html.escape(res.message)}), {len(res.iterations) - 1} iterations, residual RMS "
             f"{res.rms:.6g} N·m, {res.wall_time:.3f} s.</p>"]
    if res.unidentifiable:
        parts.append(f"<p class=warn>Not identifiable from this data: {', '.join(res.unidentifiable)}</p>")
    rows = [(e.name, e.initial, e.value, e.stderr, e.lower95, e.upper95) for e in res.estimates.values()]
    parts.append("<h2>Parameters</h2>" + table(["parameter", "start", "estimate", "std. error",
                                                  "95% low", "95% high"], rows))
    if res.correlation is not None and len(res.correlation) > 1:
        names = [n for n, e in res.estimates.items() if e.identifiable]
        parts.append("<h3>Correlation</h3>" + table([""] + names, [[n, *map(float, r)]
                                                                   for n, r in zip(names, res.correlation)]))
    fig, ax = plt.subplots(figsize=(11, 3.5))
    ax.plot(res.time, res.measured, "k", lw=0.6, label="measured")
    ax.plot(res.time, res.initial_model, "C1", lw=0.8, label="initial model")
    ax.plot(res.time, res.fitted, "C0", lw=0.8, label="fitted model")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("torque [N·m]")
    ax.legend()
    ax.grid(alpha=0.3)
    parts.append("<h2>Measured, initial and fitted torque</h2>" + figure_html(fig))
    names = list(res.iterations[0]["params"])
    fig, ax = plt.subplots(1, len(names) + 1, figsize=(3.2 * (len(names) + 1), 2.8))
    its = np.arange(len(res.iterations))
    for a, n in zip(ax, names):
        a.plot(its, [it["params"][n] for it in res.iterations], "o-")
        a.set_title(n)
        a.set_xlabel("iteration")
    ax[-1].semilogy(its, [max(it["rms"], 1e-300) for it in res.iterations], "o-")
    ax[-1].set_title("residual RMS")
    fig.tight_layout()
    parts.append("<h2>Iteration history</h2>" + figure_html(fig))
    d = res.diagnostics
    parts.append("<h2>Residual</h2><p>" + html.escape(
        f"runs test p = {d['runs_test']['p_value']:.3g} (runs {d['runs_test']['runs']}), Ljung-Box p = "
        f"{d['ljung_box']['p_value']:.3g} over {d['ljung_box']['lags']} lags: "
        f"{'white' if d['white_at_5pct'] else 'not white'} at 5%.") + "</p>")
    parts.append(residual_figures(res.time, res.residual, res.speed, res.angle))
    write_page(path, title, parts)


def write_page(path, title, parts) -> None:
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{CSS}</style></head><body>{''.join(parts)}</body></html>")
    write_text(path, page)


def diagnosis_report(out, path, title="pumpsim diagnosis") -> None:
    parts = [f"<h1>{html.escape(title)}</h1>", f"<p>{html.escape(out['method'])}.</p>"]
    rows = [("baseline", "", f"{out['baseline']['rms']:.6g}", "", "", ", ".join(
        f"{k} = {v['value']:.6g}" for k, v in out["baseline"]["params"].items() if v["value"] is not None))]
    for s in out["steps"]:
        ps = ", ".join(f"{k} = {v['value']:.5g} ± {1.96 * v['stderr']:.2g}" if isinstance(v, dict) else f"{k} = {v}"
                       for k, v in s["params"].items())
        rows.append((s["effect"], f"{s['rms_before']:.6g}", f"{s['rms_after']:.6g}", f"{s['p_value']:.3g}",
                     f"{s['bic_before']:.1f} -> {s['bic_after']:.1f}", ps))
    parts.append("<h2>Steps</h2>" + table(["effect", "RMS before", "RMS after", "p-value", "BIC",
                                           "parameters (95 % intervals)"], rows))
    f = out["final"]
    verdict = "white" if f["residual_white"] else "NOT white"
    parts.append(f"<p>Final residual RMS {f['rms']:.6g} N·m, {verdict} (runs p = {f['runs_p_value']:.3g}, "
                 f"Ljung-Box p = {f['ljung_box_p_value']:.3g}).</p>")
    if out["unexplained"]:
        parts.append("<p class=warn>Unexplained residual: no candidate effect explains it. Peaks at shaft orders "
                     + ", ".join(f"{w['order']:.3f} ({w['frequency']:.1f} Hz)" for w in out["unexplained_where"])
                     + ".</p>")
    for a, b in out["confounded"]:
        parts.append(f"<p class=warn>Confounded: {html.escape(a)} and {html.escape(b)} — a measurement at a "
                     "second speed would separate them.</p>")
    for h in out["_history"]:
        r = h["result"]
        fig, ax = plt.subplots(figsize=(11, 3))
        ax.plot(r.time, r.measured, "k", lw=0.5, label="measured")
        ax.plot(r.time, r.fitted, "C0", lw=0.8, label=f"model ({h['label']})")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("torque [N·m]")
        ax.legend()
        ax.grid(alpha=0.3)
        parts.append(f"<h2>After {html.escape(h['label'])}</h2>" + figure_html(fig))
        parts.append(residual_figures(r.time, r.residual, r.speed, r.angle))
    write_page(path, title, parts)
