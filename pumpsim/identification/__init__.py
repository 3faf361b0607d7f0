"""Identification (report §12-14): fit the vane-housing COF (and phase, speed, offsets, any numeric
config value) to measured data.

    Problem  -> Optimiser -> IdentificationResult

- `problem.py`: the Problem interface (names, start values and bounds from the registries, model
  and Jacobian) and the constant-speed problem (torque through the compiled inverse dynamics:
  the SIMD library's torques and their differences, else the CasADi map and forward AD); `joint.py`: several measurements at once; `transient.py`: a
  run-up or coast-down (speed under the measured torque, CVODES sensitivities); `start.py`: start
  values of the periodic parameters (phase scan, speed from the spectrum).
- `optimiser.py`: Gauss-Newton with relaxation factor (report §12), Levenberg-Marquardt, IPOPT,
  one interface, one FitOutcome.
- `identifiability.py`: parameters without effect or in a flat direction are named, not guessed.
- `result.py`: estimates, standard errors, 95 % intervals, correlation, history, residual
  diagnostics, provenance; `fit.py`: the driver `identify`.
"""
from .fit import adequacy_at, identify, identify_transient, make_problem
from .joint import JointProblem
from .optimiser import METHODS, FitOutcome, Optimiser, gauss_newton, ipopt_fit
from .problem import (SMOOTH_COLUMNS, ConstantSpeedProblem, Problem, base_name, half_band, parameter_map,
                      sample_torque, speed_band)
from .result import Estimate, IdentificationResult, provenance
from .transient import TransientProblem

__all__ = ["adequacy_at", "identify", "identify_transient", "make_problem", "Problem", "ConstantSpeedProblem",
           "JointProblem", "TransientProblem", "Optimiser", "FitOutcome", "METHODS", "gauss_newton",
           "ipopt_fit", "IdentificationResult", "Estimate", "provenance", "base_name", "parameter_map",
           "sample_torque", "speed_band", "half_band", "SMOOTH_COLUMNS"]
