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

# A sample where the voltage's slope jumps (its second difference) by more than STEP_SIGMAS robust
# sigmas of the log's second differences, and by more than STEP_FLOOR of the voltage's size, is a
# stop of the direct driver's steps (a step in the log; a spike). Not every sample: measured on a 5 s
# EVP log with a 13.5 -> 10 V step, every sample a stop cost 2.3 % more steps for the same error
# against an rtol 1e-9 reference (fewer error-test failures); and a threshold of 5 % of the voltage
# took the largest of 5000 samples of 0.5 % noise (4.3 sigmas) for a step.
STEP_SIGMAS = 10.0
STEP_FLOOR = 1e-3

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
        """The samples (grid indices) where the voltage steps (STEP_SIGMAS, STEP_FLOOR)."""
        v = self.values
        d2 = v[2:] - 2 * v[1:-1] + v[:-2]
        sigma = 1.4826 * np.median(np.abs(d2 - np.median(d2))) if d2.size else 0.0
        return 1 + np.nonzero(np.abs(d2) > max(STEP_SIGMAS * sigma, STEP_FLOOR * np.max(np.abs(v))))[0]
