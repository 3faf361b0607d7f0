"""The HTML page every report shares: one style sheet, tables whose numbers never wrap, figures
embedded as base64 PNG (no external files, scripts or fonts: a page opens anywhere, including
headless browsers), and the provenance block (files and their SHA-256, config, date, pumpsim
version, compiled kernel) every report starts and ends with."""
from __future__ import annotations

import base64
import html
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..io import write_text  # noqa: E402
from ..presentation import fmt_number, provenance  # noqa: E402

CSS = ("body{font-family:DejaVu Sans,Arial,sans-serif;max-width:1150px;margin:1.5em auto;color:#222;"
       "line-height:1.35}h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}"
       "table{border-collapse:collapse;margin:.4em 0}td,th{border:1px solid #bbb;padding:3px 8px}"
       "th{background:#eee;text-align:left}td.n{text-align:right;white-space:nowrap;"
       "font-variant-numeric:tabular-nums}td.t{text-align:left}span.nb{white-space:nowrap}"
       "img{max-width:100%}.warn{color:#8a3b00;background:#fff4e5;border-left:4px solid #e08a00;"
       "padding:.4em .8em}.ok{background:#eef7ee;border-left:4px solid #3a3;padding:.4em .8em}"
       "table.prov td{font-size:.85em;font-family:monospace}.note{font-size:.88em;color:#555}"
       "tr.chosen td{background:#eef7ee;font-weight:bold}tr.out td{background:#fdecea}ul.warn{margin-top:0;padding:.3em .8em .3em 2.2em}")


def figure_html(fig, tight: bool = True) -> str:
    """The figure as an embedded PNG; bbox 'tight' so no axis label is clipped. tight=False for a
    figure already laid out by tight_layout (which keeps every label inside it): the tight bbox
    would lay out every text a second time, a third of such a figure's cost."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=96, **({"bbox_inches": "tight", "pad_inches": 0.15} if tight else {}))
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
