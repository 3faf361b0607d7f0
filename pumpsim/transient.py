"""Identification on transient data: a run-up or coast-down in which the drive torque is measured
and the speed responds (torque drive of the constrained model).

The measured torque is applied sample by sample (zero-order hold); theta and omega are integrated
with CVODES over each sample interval, chained with `mapaccum`, and the model speed is compared with
the measured speed. The Jacobian d omega / d phi comes from CVODES forward sensitivities through the
compiled ode_rhs and its forward derivatives (casadi issue 4383: CVODES Jacobians with three or more
parameter directions were wrong unless error control covered the sensitivities -- `fsens_err_con`
is set and the tests compare with finite differences).
"""
from __future__ import annotations

import time as _time

import casadi as ca
import numpy as np

from .config import PumpConfig, as_array
from .data import Dataset
from .diagnostics import residual_report
from .errors import ConfigError, DataError
from .identify import (IdentificationResult, bounds_reached, fit_estimates, following, gauss_newton,
                       parameter_map, provenance, start_and_bounds)
from .kernels import load_kernels
from .model_spec.parameters import MEASUREMENT, alias_targets, layout

TRANSIENT_SPECIAL = ("mu", "mu_slot", *(m.name for m in MEASUREMENT if m.transient))


class TransientProblem:
    """Model speed omega(t_k; phi) under the measured torque, and its sensitivities."""

    def __init__(self, cfg: PumpConfig, data: Dataset, names, initial=None, rtol=1e-9, atol=1e-11):
        if data.speed is None:
            raise DataError("transient identification needs a measured speed column")
        dt = np.diff(data.time)
        if np.ptp(dt) > 1e-6 * dt.mean():
            raise DataError("transient identification needs uniformly sampled data (use --resample)")
        self.pv = cfg.parameters("constrained")
        self.kern = load_kernels(self.pv.structure)
        self.p0 = as_array(self.pv)
        index = {q.name: i for i, q in enumerate(layout(self.pv.structure))}
        self.names = list(names)
        for n in self.names:
            if n not in TRANSIENT_SPECIAL and n not in index and not alias_targets(n):
                raise ConfigError(f"unknown parameter '{n}' for transient identification")
        v = self.pv.values
        start = {"speed0": float(data.speed[0]),
                 "theta0": float(data.angle[0]) if data.angle is not None else cfg.angle}
        self.x0, self.lower, self.upper = start_and_bounds(self.names, self.pv, start, initial)
        self.y = data.speed
        self.t = data.time - data.time[0]
        n = data.n
        phi = ca.MX.sym("phi", len(self.names))
        val = {nm: phi[i] for i, nm in enumerate(self.names)}
        ratios = [v["friction.housing.static"] / max(v["friction.housing.dynamic"], 1e-300),
                  v["friction.slot.static"] / max(v["friction.slot.dynamic"], 1e-300)]
        pvec = parameter_map(index, ca.DM(self.p0), val, v["friction.slot.dynamic"], ratios, following(cfg))
        # one sample interval under a constant (measured) torque
        x = ca.MX.sym("x", 2)
        pp = ca.MX.sym("pp", self.p0.size + 1)
        ode = self.kern["ode_rhs"](x, pp[-1], pp[:-1])
        step = ca.integrator("interval", "cvodes", {"x": x, "p": pp, "ode": ode}, 0.0, float(dt.mean()),
                             {"abstol": atol, "reltol": rtol, "fsens_err_con": True})
        chain = step.mapaccum("run", n - 1)
        x0 = ca.vertcat(val.get("theta0", start["theta0"]), val.get("speed0", start["speed0"]))
        P = ca.vertcat(ca.repmat(pvec, 1, n - 1), ca.DM(data.torque[:-1]).T)
        X = chain(x0=x0, p=P)["xf"]
        omega = ca.vertcat(x0[1], X[1, :].T)
        self._f = ca.Function("speed", [phi], [omega])
        self._fj = ca.Function("speed_jac", [phi], [omega, ca.jacobian(omega, phi)])
        self.n_eval = 0

    def model(self, x):
        self.n_eval += 1
        return np.asarray(self._f(x)).ravel()

    def model_and_jacobian(self, x):
        self.n_eval += 1
        m, J = self._fj(x)
        return np.asarray(m).ravel(), np.asarray(J)


def identify_transient(cfg: PumpConfig, data: Dataset, params=("mu", "speed0"), initial=None,
                       max_iter=30) -> IdentificationResult:
    wall0 = _time.perf_counter()
    prob = TransientProblem(cfg, data, params, initial)
    m0 = prob.model(prob.x0)
    x, r, J, history, converged, message = gauss_newton(prob, prob.x0, max_iter=max_iter)
    k = len(prob.names)
    est, corr = fit_estimates(prob.names, x, prob.x0, r, J)
    w = float(np.mean(data.speed))
    diag = residual_report(r, prob.t[1] - prob.t[0], w, fitted=k)
    d = dict(zip(prob.names, x))
    theta0 = d.get("theta0", cfg.angle)
    angle = theta0 + np.concatenate([[0.0], np.cumsum(0.5 * (data.speed[1:] + data.speed[:-1]) * np.diff(data.time))])
    return IdentificationResult(
        estimates=est, iterations=history, rms=float(np.sqrt(np.mean(r**2))), converged=converged,
        message=message + " (transient: speed fitted under the measured torque)", correlation=corr,
        diagnostics=diag, method="gauss-newton/transient", wall_time=_time.perf_counter() - wall0,
        time=data.time, measured=prob.y, fitted=prob.y - r, initial_model=m0, speed=w, angle=angle,
        n_evaluations=prob.n_eval, provenance=provenance(cfg, data, prob.kern),
        on_bound=bounds_reached(prob, x))
