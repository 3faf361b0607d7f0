"""Every tolerance the tests use, with the reason it is that size."""

# Closed forms are evaluated by the compiled kernels in double precision; the position Newton solve
# converges to ~1e-16 m on ~1e-2 m lengths, so 1e-8 relative leaves six digits of margin.
CLOSED_FORM_REL = 1e-8
# Power balance: the identity tau*omega = P_friction + dE/dt holds pointwise to rounding; the mean
# of dE/dt over a sampled revolution of a smooth periodic E vanishes spectrally (trapezoid rule).
POWER_BALANCE_REL = 1e-6
# Frictionless mean torque relative to its RMS over one revolution (same spectral argument).
ZERO_MEAN_TORQUE_REL = 1e-8
# Compiled library vs in-process CasADi function: same expression graph, different evaluation
# order; 1e-12 relative (the bound).
COMPILED_REL = 1e-12
# Energy conservation in torque drive over 100 revolutions: CVODES with rtol 1e-10 accumulates
# local errors ~ steps x rtol; 1e-6 relative is what 1e4-1e5 steps at that rtol allow.
ENERGY_REL = 1e-6
ENERGY_RTOL = 1e-10
# The report form [M V; Phi_q 0] solved by LAPACK vs the per-vane closed solve.
REPORT_FORM_REL = 1e-9
