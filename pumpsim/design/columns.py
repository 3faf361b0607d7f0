"""A batch's result table as columns: the designs evaluated as arrays (DesignMap, evaluate.py)
go into the columns with one NumPy assignment per output, not a dict per design; the others
(each from its own config) row by row. The same values, row order and status texts as the row
path (`rows`), which the optimiser reads."""
from __future__ import annotations

import numpy as np

NON_FINITE = "numerical: non-finite output (check the design's values)"


def row_status(out) -> str:
    """A design the model evaluated but whose constrained solution is not physical."""
    msgs = []
    if out["lift_off"]:
        msgs.append(f"lift_off: min housing reaction {out['min_normal_force']:.4g} N < 0 (Model 2 holds "
                    "the vane on the housing; the real vane would lift off)")
    if out["paradox"]:
        msgs.append("paradox: no or several consistent slot contact-side sets")
    return "; ".join(msgs) or "ok"


class Block:
    """The outputs of B designs evaluated together at S speeds each: out name -> (B S,) in
    design-major order, omega (B S,) their speeds, fin (B S,) whether every output the study
    reports is finite."""

    def __init__(self, out: dict, omega, fin, S: int):
        self.out, self.omega, self.fin, self.S = out, np.asarray(omega, dtype=float), fin, S

    def design(self, d: int) -> "BlockDesign":
        return BlockDesign(self, d)


class BlockDesign:
    """One design's place in a Block: what evaluate.py keeps as its per-speed results."""

    __slots__ = ("block", "d")

    def __init__(self, block, d):
        self.block, self.d = block, d

    def pairs(self) -> list:
        """[(speed, outputs or None)] as the row path reads them (None: a non-finite output)."""
        b, lo = self.block, self.d * self.block.S
        return [(float(b.omega[r]), {nm: a[r].item() for nm, a in b.out.items()} if b.fin[r] else None)
                for r in range(lo, lo + b.S)]


def rows(study, X, ids, results: dict, speeds_of: dict) -> list[dict]:
    """One dict per design and speed (results: design row -> (status, per-speed results))."""
    keys = study.keys
    out_rows = []
    for j, (i, xs) in enumerate(zip(np.asarray(ids).tolist(), np.asarray(X, dtype=float).tolist())):
        base = {"design": int(i)}
        keyvals = dict(zip(keys, xs))
        status, per_speed = results[j]
        if isinstance(per_speed, BlockDesign):
            per_speed = per_speed.pairs()
        if per_speed is None:
            for w in speeds_of[j]:
                out_rows.append({**base, "speed": float(w), **keyvals, "status": status})
            continue
        for w, out in per_speed:
            if out is None:
                out_rows.append({**base, "speed": float(w), **keyvals, "status": NON_FINITE})
                continue
            out_rows.append({**base, "speed": float(w), **keyvals, **out, "status": row_status(out)})
    return out_rows


def table_columns(study, X, ids, results: dict, speeds_of: dict, spec) -> dict:
    """{column: values} in `spec`'s (store.columns) names: floats as float64 arrays (NaN where
    a row has no value), booleans as float64 (NaN: none), design as int64, status as a list."""
    X = np.asarray(X, dtype=float)
    J = len(X)
    counts = np.array([len(results[j][1]) if isinstance(results[j][1], list) else len(speeds_of[j])
                       for j in range(J)], dtype=np.int64)
    off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    R = int(off[-1])
    cols = {nm: np.full(R, np.nan) for nm, typ in spec if typ in ("float", "bool")}
    cols["design"] = np.repeat(np.asarray(ids, dtype=np.int64), counts)
    for c, k in enumerate(study.keys):
        cols[k] = np.repeat(X[:, c], counts)
    status = np.empty(R, dtype=object)
    blocks: dict = {}
    for j in range(J):
        st, per = results[j]
        if isinstance(per, BlockDesign):
            entry = blocks.setdefault(id(per.block), (per.block, [], []))
            entry[1].append(per.d)
            entry[2].append(j)
        elif per is None:
            cols["speed"][off[j]:off[j + 1]] = speeds_of[j]
            status[off[j]:off[j + 1]] = st
        else:
            for r, (w, out) in enumerate(per, start=off[j]):
                cols["speed"][r] = w
                status[r] = NON_FINITE if out is None else row_status(out)
                for nm, x in (out or {}).items():
                    if nm in cols:
                        cols[nm][r] = x
    for block, ds, js in blocks.values():
        _fill(cols, status, block, np.array(ds), off[np.array(js)])
    cols["status"] = status.tolist()
    return cols


def _fill(cols, status, block, ds, starts) -> None:
    """The rows of Block designs ds (their first rows at `starts`) into the columns."""
    S = block.S
    src = (ds[:, None] * S + np.arange(S)).ravel()
    dst = (starts[:, None] + np.arange(S)).ravel()
    cols["speed"][dst] = block.omega[src]
    fin = block.fin[src]
    s_in, d_in = src[fin], dst[fin]
    for nm, a in block.out.items():
        if nm in cols:
            cols[nm][d_in] = a[s_in]
    st = np.full(len(src), "ok", dtype=object)
    odd = ~fin | block.out["lift_off"][src] | block.out["paradox"][src]
    for r in np.flatnonzero(odd):
        st[r] = (row_status({nm: block.out[nm][src[r]] for nm in ("lift_off", "paradox", "min_normal_force")})
                 if fin[r] else NON_FINITE)
    status[dst] = st


__all__ = ["Block", "BlockDesign", "rows", "table_columns", "row_status", "NON_FINITE"]
