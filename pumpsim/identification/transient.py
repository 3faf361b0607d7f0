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

import casadi as ca
import numpy as np

from .. import interrupt
from ..config import PumpConfig
from ..data import Dataset
from ..errors import DataError
from ..model_spec.parameters import COF_ALIASES, MEASUREMENT
from ..tolerances import TRANSIENT_FIT_ATOL, TRANSIENT_FIT_RTOL
from .problem import Problem


class TransientProblem(Problem):
    """Model speed omega(t_k; phi) under the measured torque, and its sensitivities."""

    SPECIAL = COF_ALIASES + tuple(m.name for m in MEASUREMENT if m.transient)
    KIND = " for transient identification"
    RESIDUAL_UNIT = "rad/s"
    METHOD_TAG = "/transient"
    NOTE = " (transient: speed fitted under the measured torque)"

    def __init__(self, cfg: PumpConfig, data: Dataset, names, initial=None, extra=None,
                 rtol=TRANSIENT_FIT_RTOL, atol=TRANSIENT_FIT_ATOL):
        if data.speed is None:
            raise DataError("transient identification needs a measured speed column")
        dt = np.diff(data.time)
        if np.ptp(dt) > 1e-6 * dt.mean():
            raise DataError("transient identification needs uniformly sampled data (set the resample option)")
        if data.measured is not None and not np.all(data.measured):
            # the measured torque drives the model: a straight line across a gap would drive it too
            raise DataError("transient identification cannot leave out a gap in time (the torque across it "
                            "drives the model): cut the record at the gap and fit the part before or after it")
        starts = {"speed0": float(data.speed[0]),
                  "theta0": float(data.angle[0]) if data.angle is not None else cfg.angle, **(extra or {})}
        self._setup(cfg, data, names, starts, initial)
        self.y = data.speed
        phi = ca.MX.sym("phi", len(self.names))
        omega = self._speed_graph(phi, float(dt.mean()), rtol, atol)
        self._f = ca.Function("speed", [phi], [omega])
        self._fj = ca.Function("speed_jac", [phi], [omega, ca.jacobian(omega, phi)])

    def _speed_graph(self, phi, step_dt, rtol, atol):
        """The model speed at every sample as a CasADi expression of the fitted values phi."""
        val = {nm: phi[i] for i, nm in enumerate(self.names)}
        pvec = self._parameters(val, lib=ca)
        x = ca.MX.sym("x", 2)
        pp = ca.MX.sym("pp", self.p0.size + 1)  # runtime parameters and the interval's torque
        ode = self.kern["ode_rhs"](x, pp[-1], pp[:-1])
        step = ca.integrator("interval", "cvodes", {"x": x, "p": pp, "ode": ode}, 0.0, step_dt,
                             {"abstol": atol, "reltol": rtol, "fsens_err_con": True})
        n = self.data.n
        chain = step.mapaccum("run", n - 1)
        x0 = ca.vertcat(val.get("theta0", self.fixed["theta0"]), val.get("speed0", self.fixed["speed0"]))
        P = ca.vertcat(ca.repmat(pvec, 1, n - 1), ca.DM(self.data.torque[:-1]).T)
        X = chain(x0=x0, p=P)["xf"]
        return ca.vertcat(x0[1], X[1, :].T)

    def model(self, x):
        self.n_eval += 1
        with interrupt.deferred():  # CVODES' callbacks must not see a signal's exception
            return np.asarray(self._f(x)).ravel()

    def model_and_jacobian(self, x, cols=None):
        self.n_eval += 1
        with interrupt.deferred():
            m, J = self._fj(x)
        J = np.asarray(J)
        return np.asarray(m).ravel(), J if cols is None else J[:, list(cols)]

    def symbolic_model(self, phi):
        raise NotImplementedError("IPOPT fits constant-speed data")  # refused before (identify)

    def speed_of(self, x):
        """The measured mean speed (what the residual's shaft orders refer to)."""
        return self.data.mean_speed()

    def angle(self, x):
        """The rotor angle from theta0 and the measured speed (trapezoidal integral)."""
        theta0 = dict(zip(self.names, x)).get("theta0", self.fixed["theta0"])
        return theta0 + self.data.turned()

    def parameter_vector(self, x):
        return np.asarray(self._parameters(dict(zip(self.names, x))), dtype=float).ravel()
