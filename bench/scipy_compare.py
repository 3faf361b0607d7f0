"""SciPy's stiff integrators on the same compiled right-hand side and Jacobian as the runtime's
CVODES paths, for `make bench` (contact start-up case in run.py, pump-down in pumpdown.py).

SciPy gets the kernels through their C entry points (ctypes, no CasADi call per evaluation) and the
Jacobian as a dense array; the same relative tolerance and per-state absolute tolerances
(atol x the runtime's state scale). Every row is timed interleaved with the others, median of
`repeats`, and carries its error against a tight-tolerance reference: a faster run that is less
accurate is not faster."""
from __future__ import annotations

import os
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from pumpsim import cvodes_driver

METHODS = ("LSODA", "BDF", "Radau")


def compiled_ode(kern, name, inputs, jac_rows):
    """(f(t, y), jac(t, y)) over the kernel `name` (first input the state) and `name`_jac;
    jac_rows: per Jacobian output, the row offset of its block in d y'/d y, or None to skip.
    The rhs outputs are concatenated into y'."""
    so = next(Path(kern.folder).glob("*.so"))
    f, fj = kern[name], kern[name + "_jac"]
    call, jcall = (cvodes_driver.KernelCall(so, nm, inputs, 0) for nm in (name, name + "_jac"))
    sizes = [f.size1_out(k) for k in range(f.n_out())]
    n = sum(sizes)
    cuts = np.cumsum(sizes)[:-1]
    blocks = [(k, fj.sparsity_out(k), r0) for k, r0 in enumerate(jac_rows) if r0 is not None]
    tri = [(np.asarray(sp.get_triplet()[0], dtype=int) + r0, np.asarray(sp.get_triplet()[1], dtype=int))
           for _, sp, r0 in blocks]
    nnz = [sp.nnz() for _, sp, _ in blocks]

    def rhs(t, y):
        out = np.empty(n)
        call(y[:f.size1_in(0)], np.split(out, cuts))
        return out

    def jac(t, y):
        bufs = [None] * fj.n_out()
        for (k, _, _), m in zip(blocks, nnz):
            bufs[k] = np.empty(m)
        jcall(y[:f.size1_in(0)], bufs)
        J = np.zeros((n, n))
        for (k, _, _), (r, c) in zip(blocks, tri):
            J[r, c] = bufs[k]
        return J

    return rhs, jac


def scipy_run(rhs, jac, y0, t_end, t_eval, method, rtol, atol):
    from scipy.integrate import solve_ivp

    sol = solve_ivp(rhs, (0.0, t_end), y0, method=method, rtol=rtol, atol=atol, jac=jac, t_eval=t_eval)
    return sol


@contextmanager
def casadi_plugin():
    """The runtime's CVODES through CasADi's plugin instead of the direct driver."""
    old = os.environ.get(cvodes_driver.ENV)
    os.environ[cvodes_driver.ENV] = "casadi"
    try:
        yield
    finally:
        if old is None:
            del os.environ[cvodes_driver.ENV]
        else:
            os.environ[cvodes_driver.ENV] = old


def interleaved(rows: dict, repeats=3) -> dict:
    """rows: name -> fn() returning a result dict; each timed `repeats` times in turn; the median
    wall time and the last run's result per row. A result's "wall" (the integration alone, when
    the call also evaluates outputs SciPy's rows do not) replaces the call's wall time."""
    times = {k: [] for k in rows}
    last = {}
    for _ in range(repeats):
        for name, fn in rows.items():
            t0 = time.perf_counter()
            last[name] = fn()
            times[name].append(last[name].pop("wall", time.perf_counter() - t0))
    return {k: {"seconds": float(np.median(v)), "all_seconds": v, **last[k]} for k, v in times.items()}


def print_table(title, res):
    """The rows with their wall time, the ratio to the best SciPy method and their error."""
    sc = [k for k in res if k.startswith("SciPy")]
    best = min(sc, key=lambda k: res[k]["seconds"]) if sc else None
    print(f"\n{title}")
    print(f"{'integrator':<32}{'wall [s]':>10}{'vs best SciPy':>15}{'steps':>9}{'rhs':>9}{'Jac':>7}  error vs reference")
    for k, r in res.items():
        ratio = res[best]["seconds"] / r["seconds"] if best else float("nan")
        steps = "-" if r.get("steps") is None else r["steps"]
        print(f"{k:<32}{r['seconds']:>10.3f}{ratio:>14.2f}x{steps:>9}{r.get('rhs', 0):>9}"
              f"{r.get('jac', 0):>7}  {r.get('error_text', '')}")
    return best


def at_equal_accuracy(res, best, keys, prefix="compiled CVODES, direct"):
    """Best SciPy's time over that of the fastest direct-driver row at least as accurate in every
    error in `keys` (None when no row is): the figure the target is held to."""
    ok = [k for k in res if k.startswith(prefix) and all(res[k].get(e, np.inf) <= res[best].get(e, 0) for e in keys)]
    if not ok:
        return None, None
    k = min(ok, key=lambda k: res[k]["seconds"])
    return res[best]["seconds"] / res[k]["seconds"], k


def report_ratio(res, best, keys, indent=""):
    """Print and return the two ratios: at the same tolerances, and at equal or better accuracy."""
    same = res[best]["seconds"] / res["compiled CVODES, direct driver"]["seconds"]
    fair, row = at_equal_accuracy(res, best, keys)
    print(f"{indent}direct driver vs best SciPy ({best}): {same:.2f}x at the same tolerances; "
          + (f"{fair:.2f}x at equal or better accuracy ({row})" if fair else "no direct row as accurate")
          + f" (target >= 1.5x: {'met' if fair and fair >= 1.5 else 'MISSED'})")
    return {"speedup_same_tolerances": same, "speedup_equal_accuracy": fair, "equal_accuracy_row": row,
            "target_met": bool(fair and fair >= 1.5)}
