"""Several measurements fitted together: shared physics (COFs, geometry, effects), per-measurement
phase, speed and delay. Data at two speeds separates what one speed cannot (a torque offset from a
viscous tip force, or from the COF on a concentric rig).

Per-measurement parameters are named `theta0@i`, `speed@i`, `delay@i` (i counts from 0); naming
plain `theta0` fits one per measurement.
"""
from __future__ import annotations

import numpy as np

from .problem import ConstantSpeedProblem, Problem, base_name

LOCAL = ("theta0", "speed", "delay")


class JointProblem(Problem):
    """The Problem interface over stacked constant-speed measurements (one sub-problem each)."""

    SPECIAL = ConstantSpeedProblem.SPECIAL

    def __init__(self, cfg, datasets, names, initial=None, extra=None, ripple_order: int = 1,
                 speed_in_band: bool = False):
        initial, extra = initial or {}, extra or {}
        K = len(datasets)
        self.names = []
        for n in names:
            for m in ([f"{n}@{i}" for i in range(K)] if n in LOCAL else [n]):
                if m not in self.names:
                    self.names.append(m)
        self.shared = [n for n in self.names if "@" not in n]
        self.subs, self.cols = [], []
        for i, ds in enumerate(datasets):
            local = [n for n in self.names if n.endswith(f"@{i}")]
            mine = lambda d: {base_name(k): v for k, v in d.items() if "@" not in k or k.endswith(f"@{i}")}  # noqa: E731
            self.subs.append(ConstantSpeedProblem(cfg, ds, self.shared + [base_name(n) for n in local],
                                                  mine(initial), mine(extra), ripple_order, speed_in_band))
            self.cols.append(np.array([self.names.index(n) for n in self.shared + local]))
        self.cfg, self.data, self.kern, self.fixed = cfg, datasets, self.subs[0].kern, self.subs[0].fixed
        self.x0, self.lower, self.upper = (self._gather(lambda s: s.x0), self._gather(lambda s: s.lower),
                                           self._gather(lambda s: s.upper))
        self.y = np.concatenate([s.y for s in self.subs])
        self.rows = np.cumsum([0] + [s.y.size for s in self.subs])

    def _gather(self, get):
        x = np.empty(len(self.names))
        for s, c in zip(self.subs, self.cols):
            x[c] = get(s)
        return x

    @property
    def n_eval(self):
        return sum(s.n_eval for s in self.subs)

    @property
    def dt(self):
        return self.subs[0].dt

    def model(self, x):
        return np.concatenate([s.model(x[c]) for s, c in zip(self.subs, self.cols)])

    def model_and_jacobian(self, x, cols=None):
        cols = list(range(len(self.names))) if cols is None else list(cols)
        m = np.empty(self.y.size)
        J = np.zeros((self.y.size, len(cols)))
        for s, c, lo, hi in zip(self.subs, self.cols, self.rows[:-1], self.rows[1:]):
            mine = [i for i, ci in enumerate(c) if ci in cols]  # the sub-problem's columns asked for
            if not mine:
                m[lo:hi] = s.model(x[c])
                continue
            m[lo:hi], J[lo:hi, [cols.index(c[i]) for i in mine]] = s.model_and_jacobian(x[c], mine)
        return m, J

    def keep_at(self, x):
        keeps = [s.keep_at(x[c]) for s, c in zip(self.subs, self.cols)]
        if all(k is None for k in keeps):
            return None
        return np.concatenate([np.ones(s.y.size, bool) if k is None else k for s, k in zip(self.subs, keeps)])

    def symbolic_model(self, phi):
        raise NotImplementedError("IPOPT fits one measurement")  # refused before (make_problem's caller)

    def angle(self, x):
        return np.concatenate([s.angle(x[c]) for s, c in zip(self.subs, self.cols)])

    def time_axis(self):
        """The measurements one after the other (each shifted to start where the last ended)."""
        out, t0 = [], 0.0
        for s in self.subs:
            out.append(s.t + t0)
            t0 = out[-1][-1] + s.dt
        return np.concatenate(out)

    def speed_of(self, x):
        return self.subs[0].speed_of(x[self.cols[0]])

    def parameter_vector(self, x):
        return self.subs[0].parameter_vector(x[self.cols[0]])

    def start(self, x):
        x = np.array(x, dtype=float)
        for s, c in zip(self.subs, self.cols):
            x[c] = s.start(x[c])
        return x
