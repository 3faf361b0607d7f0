"""A supply voltage given as samples (a bench log's), in place of the constant motor.voltage.

The voltage is linear between the samples on a uniform grid from the run's start, and beyond the
grid's ends the end intervals' lines (as CasADi's linear interpolant and the direct CVODES
driver's C take it: one definition on both integration paths). The direct driver gets the samples
and interpolates them before every kernel call, its steps ending on the samples where the voltage
steps (`stops`: cvodes_driver.Driver.set_drive); CasADi's plugin gets `function`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

# A sample where the voltage's slope jumps by more than this share of its largest size within one
# sample interval (a step in the log) is a stop of the direct driver's steps. Measured on a 5 s EVP
# log with a 13.5 -> 10 V step, every sample a stop: 2.3 % more steps, fewer error-test failures,
# the same error against an rtol 1e-9 reference; so not at every sample: a log's noise (0.5 % of
# the voltage gives second differences of 1.2 % rms) is no step.
STEP_SHARE = 0.05

@dataclass(eq=False)
class VoltageDrive:
    step: float  # s between samples
    values: np.ndarray = field(repr=False)  # V at 0, step, 2 step, ...

    def __post_init__(self):
        self.values = np.ascontiguousarray(self.values, dtype=float).ravel()
        if self.values.size < 2 or not self.step > 0:
            raise ValueError("a voltage drive needs at least 2 samples and a positive step")

    def __call__(self, t):
        """The voltage at t [s from the run's start] (float or array)."""
        s = np.asarray(t, float) / self.step
        i = np.clip(np.floor(s), 0, self.values.size - 2).astype(int)
        f = s - i
        v = self.values[i] * (1 - f) + self.values[i + 1] * f
        return float(v) if v.ndim == 0 else v

    @cached_property
    def function(self) -> ca.Function:
        """The same voltage as a CasADi function of time (CasADi's CVODES plugin)."""
        grid = self.step * np.arange(self.values.size)
        return ca.interpolant("bench_voltage", "linear", [grid.tolist()], self.values.tolist())

    @cached_property
    def stops(self) -> np.ndarray:
        """The samples (grid indices) where the voltage steps (STEP_SHARE)."""
        v = self.values
        jump = np.abs(v[2:] - 2 * v[1:-1] + v[:-2])
        return 1 + np.nonzero(jump > STEP_SHARE * np.max(np.abs(v)))[0]
