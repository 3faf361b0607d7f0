"""The BLAS threads of pumpsim's own linear algebra.

A fit's or a diagnosis's linear algebra is small solves (a few columns by thousands of samples,
least squares and SVDs of a few hundred rows); the compiled kernels thread themselves. A second
OpenBLAS thread there buys nothing and, between solves, spins: on a 2-core machine it cost a
5,000-sample diagnosis 0.3-0.4 s of its 3.6 CPU s, with bit-identical results. So the command
line sets one thread before NumPy loads (`one_blas_thread`), and the API's fitting entry points
run under `small_solves`; a thread count the user set (any of BLAS_THREADS in the environment)
is kept in both."""
from __future__ import annotations

import contextvars
import functools
import os

# the BLAS libraries NumPy and SciPy may load, and the variable each reads its thread count from
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")

_inside = contextvars.ContextVar("pumpsim_small_solves", default=False)


def one_blas_thread(environ=os.environ) -> None:
    """One BLAS thread for a command's process unless the user set a count. Read when NumPy loads
    its BLAS, so call before: the CLI imports NumPy only after this."""
    for name in BLAS_THREADS:
        environ.setdefault(name, "1")


def user_set_threads(environ=os.environ) -> bool:
    return any(name in environ for name in BLAS_THREADS)


def small_solves(fn):
    """Run `fn` with the loaded BLAS libraries on one thread (threadpoolctl; restored after),
    unless the user set a count or an enclosing call already did. The limit is the process's:
    two Python threads fitting at once share it."""
    @functools.wraps(fn)
    def limited(*args, **kwargs):
        if _inside.get() or user_set_threads():
            return fn(*args, **kwargs)
        from threadpoolctl import threadpool_limits
        token = _inside.set(True)
        try:
            with threadpool_limits(limits=1, user_api="blas"):
                return fn(*args, **kwargs)
        finally:
            _inside.reset(token)
    return limited
