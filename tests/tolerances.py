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
# Discrepancy workflow (issue 5), each effect alone at effect-RMS / noise-sigma = 5, 1001 samples:
# an effect parameter's standard error is ~ 1/(5 sqrt(n)) of its size ~ 0.6 %, so 10 % is ~15 sigma
# of room for the fit's own bias; mu within 1 %; the final residual RMS within 1.15 sigma (a white
# residual of 1001 samples has RMS sigma (1 +- 0.03)).
EFFECT_PARAM_REL = 0.10
EFFECT_MU_REL = 0.01
EFFECT_FINAL_RMS = 1.15
# A sensor low-pass on the continuous torque is made in the tests by filtering a simulation this
# many times finer than the samples: twice the model's own LAG_SUBSTEPS, so the test data is not
# the model's discretisation (the sub-sample error halves with each doubling, measured).
SENSOR_TRUTH_SUBSTEPS = 8
# CVODES vs IDAS on the contact model (two BDF codes, explicit ODE vs implicit residual) at rtol
# 1e-8 over 0.01 s of stiff contact (~800 steps): the global error is ~1e2-1e3 x rtol (observed
# 5e-6 of the RMS torque); 1e-4 leaves 20x room and still fails on any modelling difference.
INTEGRATOR_CROSS_REL = 1e-4
# SIMD library vs scalar library: the same SX instructions, vector libm (<= 4 ulp) and FMA
# contraction instead of correctly rounded scalar calls (observed 1e-14 of each output's scale);
# 1e-10 relative is the bound. The position residual is rounding noise (~1e-17 m) in both:
# compared absolutely, in units of the housing size.
SIMD_REL = 1e-10
# The SIMD library's Jacobian entries vs forward AD on the CasADi map: both exact derivatives of the
# same SX expressions, summed in another order (reverse sweep and contraction vs forward sweep; FMA
# contraction, vector libm): observed <= 4e-11 of a column's scale (a column zero in exact
# arithmetic: of the torque over the input's size), 1e-10 is the bound. Against central differences
# (step 1e-6 of each input's scale, where the one-sided ones agree): truncation ~1e-12 and rounding
# ~1e-16 / 1e-6 = 1e-10 of the scale, observed ~1e-8 near kinks just outside the step: 1e-6.
SIMD_JACOBIAN_REL = 1e-10
# A derivative zero in exact arithmetic (a concentric housing's centre): the vanes' contributions
# cancel in another order; observed 5e-10 of the torque over the input's size, bound 1e-9 -- 10x
# inside identifiability's NO_EFFECT_REL (1e-8), which must still call such a column no effect.
SIMD_JACOBIAN_ZERO = 1e-9
SIMD_JACOBIAN_FD_REL = 1e-6
# The fits' columns on the SIMD library vs on the CasADi map: SIMD_JACOBIAN_REL, except the lag's
# (both paths: a finite step 1e-6 T of the filter applied to torques equal to ~1e-15, observed 6e-9).
FIT_LAG_COLUMN_REL = 1e-7
# Columns the model makes equal (opposite vanes' COF factors on an ellipse): 1e-9 of their norm, 10x
# inside score_test's rank tolerance (1e-8 of the normalised columns; AD's differ by ~1e-15).
EQUAL_COLUMNS_REL = 1e-9
# Design optimisation (issue 14): kernel-AD gradients vs central differences of the whole pipeline
# with a relative step of 1e-6: truncation ~ h^2 f''' ~ 1e-12, rounding ~ eps f / h ~ 1e-10 of the
# output (observed 2.5e-10 on the ellipse, seven keys); 1e-8 of the gradient's scale fails on any
# missing chain-rule term (those are O(1)).
DESIGN_GRADIENT_REL = 1e-8
# Sobol' indices vs their known values: each comparison uses SALib's 95 % bootstrap half-width;
# with six intervals checked at once one would fail 26 % of the time, so each may use 1.5 of its
# half-width (99.7 % per interval, ~2 % for the family).
SOBOL_INTERVAL_FACTOR = 1.5
# Pneumatic model (spec §8). Cell volumes: Gauss-Legendre on the housing arc against adaptive
# quadrature of the housing area and of the vane outline: both at rounding, 1e-11 relative.
CELL_IDENTITY_REL = 1e-11
# dV/dtheta (exact, by forward AD through the kinematics) against a central difference with step
# 1e-5 rad: truncation ~ h^2 V''' / 6 ~ 1e-10 of the volume scale, rounding ~ 1e-16 / h.
CELL_DERIVATIVE_REL = 1e-7
# The friction law's cubic STEP evaluated in double precision: values <= 2 carry a few ulps
# (~1e-16); 1e-12 absolute leaves four digits of room and still fails on any formula difference
# (the smallest hand-evaluated digit tested is 1e-6).
LAW_ABS = 1e-12
# One closed formula (the derived vane inertia) evaluated by two code paths in double precision:
# a few ulps apart; 1e-14 relative.
ROUNDING_REL = 1e-14
# A fit's seed-matrix column is the central difference of the (affine) parameter map over a unit
# step; subtracting parameter values of size ~0.5 to get slopes of size ~1e-5 loses ~5 digits of
# the 16, so 1e-9 relative.
SEED_REL = 1e-9
# Compiled kernel vs NumPy lambdified from the same SymPy (codegen/numpy_model.py): the same
# formulas in another operation order and libm, both position solves at rounding; 1e-11 relative.
NUMPY_CROSS_REL = 1e-11
# Integrator state scaling: the scaled run and the run with the equivalent absolute tolerance
# take the same steps (asserted); what differs is rounding in the scaled arithmetic over ~50
# steps, 1e-9 relative ...
SCALING_SAME_REL = 1e-9
# ... and both are right: CVODES at rtol 1e-6 over 2.4 periods of an oscillator has a global
# error ~1e2 x rtol; 1e-4 of the amplitude.
OSCILLATOR_REL = 1e-4
# The report form's drive row is qdd_theta = omegadot exactly: LAPACK returns it to a few ulps.
DRIVE_ROW_REL = 1e-12
# sddot from the report form vs the per-vane closed solve, absolutely where sddot passes zero
# (elsewhere it is 1e2-1e4 m/s^2, so this floor is 1e-13..1e-11 of it).
SDDOT_FLOOR_ABS = 1e-9  # m/s^2
# Phi(q) at the solved positions: the position solve closes to ~1e-16 m on ~1e-2 m lengths.
CONSTRAINT_ABS = 1e-13  # m
# Torque drive with friction and no torque: the energy may only fall; a sample-to-sample rise above
# 1e-9 of the initial energy is more than CVODES at rtol 1e-9 can produce.
MONOTONE_ENERGY_REL = 1e-9
# Forward then inverse dynamics: the forward kernel's Newton on omegadot converges to rounding
# (the torque is piecewise affine in omegadot), so the inverse returns the applied torque to 1e-10.
FORWARD_INVERSE_REL = 1e-10
# omegadot against np.gradient of the integrated speed sampled at 2 kHz: a second-order difference
# that friction-reversal kinks make first order locally; 2 % relative plus 0.1 % of the largest
# |omegadot| where it passes zero.
GRADIENT_REL, GRADIENT_FLOOR = 2e-2, 1e-3
# Transient fit (40 samples, speed noise 0.01 rad/s): the COF's standard error is ~0.1 %; 0.5 % is
# ~5 sigma, and the start speed within 0.02 rad/s (2 sigma of one sample's noise).
TRANSIENT_MU_REL = 5e-3
TRANSIENT_SPEED0_ABS = 0.02  # rad/s
# CVODES sensitivities vs central differences (step 1e-4 of the value, integration at rtol 1e-12):
# truncation ~1e-8, so 1e-5 of the column's scale; theta0 moves the friction kinks in time, where
# the difference quotient smears a step over 2h: 2e-3.
SENSITIVITY_REL, SENSITIVITY_THETA0_REL = 1e-5, 2e-3
# Steady section of a synthetic run-up: the speed reaches its plateau at 0.3 s and leaves it at
# 0.8 s; a 1 % speed band puts the edges 0.003 s inside; 0.002 s is 10 samples at 5 kHz.
STEADY_EDGE_ABS = 0.002  # s
# Identification on noise-free signals (report signals 1-2, starts 40-70 % off): the estimate is
# limited by the stopping rule (relative step 1e-6) and the sample-averaged phase columns; 0.5 %
# leaves room for both and still rejects a wrong minimum; phase within 0.01 rad, speed 0.1 rad/s.
NOISE_FREE_MU_REL = 5e-3
FIT_THETA0_ABS, FIT_SPEED_ABS = 0.01, 0.1  # rad, rad/s
# 5 % noise on 2000 samples: the COF's standard error is ~0.1-0.3 %; 1 % is a few sigma.
NOISY_MU_REL = 1e-2
# Levenberg-Marquardt and IPOPT on noise-free data reach Gauss-Newton's minimum to their stopping
# tolerances.
METHODS_AGREE_REL = 1e-4
# AD columns vs central differences with a 1e-6 relative step: truncation ~1e-12, rounding
# ~1e-10 of the torque scale; 1e-5 relative.
FD_DIRECT_REL = 1e-5
# Angle-acting columns (sample-averaged derivative) vs the pointwise derivative on a smooth pump
# sampled at 100 kHz: they differ by O((k omega dt)^2 / 6) ~ 2e-4 for the 8th order at 471 rad/s.
FD_ANGLE_REL = 1e-3
# The closed-form rotor angle vs its central difference (step 1e-6): rounding of ~10 rad angles.
ANGLE_FD_REL, ANGLE_FD_ABS = 1e-6, 1e-8
# Requested Jacobian columns vs the full Jacobian: the same graph with fewer seed directions.
COLUMNS_REL, COLUMNS_ABS_FRAC = 1e-12, 1e-15
# A vane resting on the slot bottom: the simulated bottom force against the quasi-static analytic
# one (the penalty spring's transient and the np.gradient speed derivative): 2 % relative plus
# 0.1 % of the largest force where it passes zero.
QUASI_STATIC_REL, QUASI_STATIC_FLOOR = 2e-2, 1e-3
# Rounded tip, no friction or damping: energy drift at rtol 1e-10 below 1e-7 and below 0.2 of the
# rtol 1e-8 drift (it shrinks with the tolerance: conservative, not a modelling leak).
CONTACT_ENERGY_DRIFT, CONTACT_DRIFT_SHRINK = 1e-7, 0.2
# With contact damping: the energy falls by > 1e-4 over 0.05 s, and never rises by more than the
# integrator error at rtol 1e-10 (1e-9 of the energy) between samples.
DAMPED_ENERGY_LOSS, DAMPED_ENERGY_RISE = 1e-4, 1e-9
# The located housing-contact time vs the free-flight closed form: Illinois root finding on the
# rtol 1e-10 integration locates it to ~1e3 x rtol of the flight time.
CROSSING_REL = 1e-6
# The contact laws against the spec formulas in NumPy: the same arithmetic, rounding only.
CONTACT_LAW_REL = 1e-12
# Design-study gas outputs (issue 14, spec §9) vs a full pump-down (spec §8) averaged over
# 0.3-0.4 s, after the motor's run-up (time constant ~0.03 s), while the booster falls 3 %: the
# study's periodic steady state holds the booster at the window's mean pressure. Flow, gas power
# and speed are near-linear in p over the window (observed <= 0.3 %): 1 %. The current also
# follows the falling pressure through the motor's lag (observed 2.1 %): 3 %.
GAS_FLOW_VS_PUMPDOWN_REL = 0.01
GAS_CURRENT_VS_PUMPDOWN_REL = 0.03
# a study's revolution of the gas model's periodic steady state: means over the study's angles
# (interpolated) against time means of the run (the map's quadratures) differ by the speed
# ripple's share under the motor (measured 4e-4 on the EVP example)
GAS_STUDY_BALANCE_REL = 2e-3
# Data written in other units (N·mm, mN·m, rpm, ms, decimal comma) with 10 significant digits and
# read back: the printing rounds to 5e-11 relative, each conversion adds rounding; 1e-9 relative.
DATA_UNIT_REL = 1e-9
# Two kernel evaluations at different rotor/housing angles compared with each other, each within
# CLOSED_FORM_REL of the exact value: their sum with margin.
ROTATION_INVARIANCE_REL = 10 * CLOSED_FORM_REL
# The bundled rig record (report §14: "the COF, 0.203"): the fit gives 0.20295 +- 0.00009; every
# way of reading the record (paths, arrays, other units, CLI) must reproduce the report's value to
# 1 %, which a unit slip (x1000, rpm for rad/s) or a lost column cannot.
RIG_MU, RIG_MU_ABS = 0.203, 0.002
# Study outputs that are zero on a pump (ripple of a concentric rig ~1e-16) compared absolutely
# (~100 ulps of unit-size quantities).
DESIGN_OUTPUT_FLOOR_ABS = 1e-14
# A sum of a few same-signed terms against its parts, computed separately: a few ulps.
PARTS_SUM_REL = 1e-12
# The same computation run again (another batch, worker or call): rounding only.
REPEAT_REL = 1e-12
# Design optimum vs its closed form: a bound that is active is reached to the projection's rounding
# (1e-9); a constraint that is active to SLSQP's tolerance (ftol 1e-9 on a unit-scaled objective).
DESIGN_OPTIMUM_BOUND_REL, DESIGN_OPTIMUM_REL = 1e-9, 1e-8
# An input that does not act on an output (slot radius on a concentric rig's torque): its Morris
# mu* is the rounding of the outputs' differences, below 1e-12 of an acting input's.
NO_EFFECT_SHARE = 1e-12
# Model 1 (penalty contact, k = 5e4..1e6 N/m) in periodic steady state vs Model 2: the tip sits
# N/k deeper (observed 0.2 % on the rig at 5800 rpm, 0.54 % at 471 rad/s, ~2 % dynamic
# amplification on the ellipse at k = 5e4 that falls with k): 1 %.
CONTACT_VS_CONSTRAINED_REL = 1e-2
# From k = 5e4 to 1e6 N/m (20x) the static offset N/k falls 20x (ratio 0.05); 0.15 leaves room for
# the dynamic part, which falls more slowly, and still fails if the deviation does not shrink with k.
STIFFNESS_CONVERGENCE_RATIO = 0.15
# A figure's y axis spans more than 1e-6 of its values: not a zoom into rounding noise.
AXIS_SPAN_MIN_REL = 1e-6
# Order amplitudes and peak-to-peak from angle-domain resampling of 20001 samples over 3.4
# revolutions (1e-3 rad spacing): interpolation errs by ~(k dtheta)^2 / 8 ~ 1e-5 of an order-8
# amplitude; 1e-4 absolute on a unit torque.
ORDER_AMPLITUDE_ABS = 1e-4
# Sample statistics of 4096 quasi-random draws: a mean within 4 of its standard errors (QMC does
# better than MC); a standard deviation within 5 % (its relative spread is 1/sqrt(2 n) = 1.1 % for
# MC: ~4.5 sigma); a 5 % lognormal's mean within 0.5 % (its standard error 0.08 %: ~6 sigma); the
# truncated normal's sd (0.0197) within 0.001 (5 %).
MEAN_SIGMAS, SAMPLE_SD_REL, SAMPLE_MEAN_REL, TRUNCNORM_SD_ABS = 4, 0.05, 0.005, 1e-3
# The friction law's continuity check: the largest jump on a grid is the largest slope times the
# step; 1 % above it for the grid's uneven (by ulps) steps.
CONTINUITY_MARGIN = 1.01
# The AR(1) inflation factor of the intervals when two hidden effects leave a correlated residual
# (the rig's white residual gives ~1): above 1.5.
OPTIMISTIC_FACTOR_MIN = 1.5
# Display rules (presentation): a shown value within a tenth of its standard error of the estimate,
# the standard error with two significant digits (rounding <= 5 % when its leading digit is 1).
DISPLAY_VALUE_SE, DISPLAY_SE_REL = 0.1, 0.05
# Frictionless torque drive over a nominal 100 revolutions at 300 rad/s: the speed varies with the
# vanes' motion by a few %, so at least 95 % of the revolutions; the vanes must exchange energy
# with the rotor (each vane's energy swings by > 1 %) for the conservation test to mean anything.
REVOLUTIONS_SHARE, VANE_ENERGY_SWING_MIN = 0.95, 0.01
# With friction and no torque, 0.05 s from 200 rad/s loses more than 10 % of the energy.
FRICTION_ENERGY_KEPT_MAX = 0.9
# The solver study over 2 revolutions: every method's torque within 20 % of the reference's peak
# (RK4 at its default step and IDAS at loose tolerances included): a sanity bound, not accuracy.
SOLVER_STUDY_DEVIATION_MAX = 0.2
# A study's idle split (RunStats.idle_*) is built from the tasks' wall-clock spans (time.time),
# the total from perf_counter: the two clocks agree to microseconds over a few seconds; 1 ms.
CLOCK_ABS = 1e-3  # s
# Model 1 with gas (issue 15). With equal (zero) gas pressures the gas-coupled contact kernel and
# the mechanical contact kernel evaluate the same vane equations; the gas terms are exact zeros
# or cancel to rounding: 1e-12 of each output's scale.
GAS_CONTACT_MECH_REL = 1e-12
# Stiff frictionless contact vs Model 2 with gas, last of three revolutions at 400 rad/s: the tip
# sits delta = N/k deeper (~0.8 um at k = 1e7 for ~8 N) and the vane's position, the cells and the
# inertia terms move by O(delta / L) (L = 10 mm: 8e-5; observed 0.9-1.1 delta_max / L): the
# deviation is asserted below twice that size and to fall with k by at least 1/3 per decade (1/10
# ideal, ~1/7 observed: k rtol s is the integration floor).
PENALTY_OFFSET_FACTOR = 2.0
PENALTY_FALL_PER_DECADE = 1 / 3
# With slot friction the free vane creeps while its sliding speed is below v_static (a regularised
# stiction with viscous slope mu_s |F| / v_s ~ 8e3 N s/m against k = 1e7 N/m: a 0.8 ms time
# constant, a fifth of a revolution): not a penalty effect, it does not fall with k. The mean
# torque stays within 1e-3 (observed 2.5e-4) and the RMS torque deviation within 1 % (observed
# 0.7 %), the mechanical contact model's own bound (tests/integration/test_contact_model.py).
STICTION_MEAN_TORQUE_REL, STICTION_RMS_TORQUE_REL = 1e-3, 1e-2
# Shaft work = friction + contact + kinetic energy change - work of the gas forces on vanes and
# rotor: a pointwise identity of the right-hand side integrated by CVODES at rtol 1e-9 over ~1e4
# steps (observed 3e-10 at rtol 1e-9, 3e-11 at 1e-10); 1e-7 relative.
CONTACT_GAS_ENERGY_REL = 1e-7
# The cells' boundary crosses the tip-housing penetration along the housing normal (a segment of
# length |delta| that is not vane material): gas power and the gas forces' power agree to rounding
# at delta = 0 and differ to first order in delta. Linearity: the difference at 10 delta is 10x
# the one at delta within 10 % (second-order terms are O(delta / rho) ~ 1e-3).
PARTITION_LINEARITY_REL = 0.1
# Independent Model 2 (bench/independent/rig.py, own derivation) vs pumpsim simulate: both solve the
# same equations exactly (tip position to ~1e-16 m, analytic s', s'', 3x3 reaction solve), so only
# rounding separates them (observed <= 5e-10 of the RMS torque through 10-digit CSV, ~1e-13 in
# process); 1e-8 of the RMS torque is 100x the 1e-6 target and far above rounding.
INDEPENDENT_RIG_REL = 1e-8
# Data formats written by the independent generator, read back by pumpsim.load_data: values are
# written with >= 7 significant digits (%.9g in the ';' decimal-comma file, %.6f N mm), so 1e-6
# of the torque RMS is what the printed digits allow.
INDEPENDENT_FORMAT_REL = 1e-6
# The independent generator's low-pass sensor (first-order hold on LAG_OVERSAMPLING = 64 sub-steps
# per sample) against the same filter on 512 sub-steps: the error falls as 1/oversampling (measured
# 0.072, 0.036, 0.018, 0.009 noise sigma at SNR 5 for 8, 16, 32, 64 on the 3-vane ellipse); 0.02 of
# the torque's ripple RMS bounds the 64x error with a 2x margin over that 1/n law.
INDEPENDENT_LOWPASS_REL = 0.02
# Motion of the independent generator (ripple + slow drift, closed form) against central
# differences on a 1 us step (truncation ~ h^2 omega''/6 ~ 1e-9 relative, rounding ~ 1e-16 x theta / h).
INDEPENDENT_MOTION_REL = 1e-7
# Observable share (RMS share of an effect no mu/phase change mimics) of an exact phase shift: the scan's
# 0.0005 rad grid plus a linear phase column leave ~1e-7 (measured 9e-8); a friction reversal crossing a
# sample between grid point and truth would leave ~1e-3 on 2000 samples, still far below the 0.1 of a real
# 50 um radial move (measured 0.18).
INDEPENDENT_PHASE_SHARE = 1e-2
# Integrator settings of test scenarios (not comparisons): each is tighter than the tolerance its
# test compares with, by the margin given there. Synthetic "measured" runs are integrated 100x
# tighter than the transient fit integrates (TRANSIENT_FIT_RTOL 1e-9), so the data's own
# integration error is far below both its noise and the fit's.
TRUTH_RTOL, TRUTH_ATOL = 1e-11, 1e-13
# The sensitivity check integrates at 1e-12 (see SENSITIVITY_REL: truncation of the difference
# quotient ~1e-8 must dominate the integration error).
SENSITIVITY_RTOL, SENSITIVITY_ATOL = 1e-12, 1e-14
# Torque drive: monotone energy at rtol 1e-9 (MONOTONE_ENERGY_REL), forward vs inverse at 1e-10
# (FORWARD_INVERSE_REL); positions [rad, m] of size 1e-2..1e2 with absolute tolerance 1e-12.
MONOTONE_ENERGY_RTOL, FORWARD_INVERSE_RTOL, POSITION_ATOL = 1e-9, 1e-10, 1e-12
# The oscillator of the state-scaling test at rtol 1e-6 (OSCILLATOR_REL is its global error).
OSCILLATOR_RTOL = 1e-6
# -- pneumatic model (spec §8), moved from tests/pneumatics ------------------------------------
# Port overlap length: PORT_NODES = 3 Gauss-Legendre nodes on the housing arc (~1e-5 accurate on
# these arcs) against adaptive quadrature; 1e-4 relative leaves 10x room.
PORT_ARC_REL = 1e-4
# Budgets of the gas model integrated at rtol 1e-10 (the quadratures ride with the states): local
# errors ~ 1e3 steps x rtol per revolution, so 1e-6 relative leaves room.
GAS_ENERGY_REL = 1e-6
# ... and the tolerances they are integrated at (atol relative to each state's nominal size,
# pneumatics.run.state_scale): 1e-10 keeps the integration error ~1e3 x below GAS_ENERGY_REL.
GAS_BUDGET_RTOL, GAS_BUDGET_ATOL = 1e-10, 1e-12
# Equal pressures on both sides of every vane: the gas loads cancel and the gas model's torque and
# normal force are Model 2's to rounding (same expression graph up to the cancelling loads).
EQUAL_PRESSURE_REL = 1e-12
# Reynolds transport: load power + gas power vanish identically; summed over ~20 pieces, rounding
# of ~1e-16 x piece size relative to the largest power.
LOAD_POWER_REL = 1e-11
# Motor drive: omegadot from two Newton steps on a piecewise-affine residual (exact on one contact
# branch); the residual left is rounding (N m).
MOTOR_RESIDUAL_ABS = 1e-9
# Compiled orifice law against the textbook formula: same closed form, different evaluation order.
ORIFICE_REL = 1e-12
# Choked flow: the kernel clamps the pressure ratio at the critical one, so the flow is identical
# to the last bit for any lower downstream pressure (1e-14: a few ulp).
CHOKED_FLAT_REL = 1e-14
# Closed adiabatic cell over one revolution at rtol 1e-10: p V^gamma constant to the integrator's
# accumulated error (~1e3 steps x 1e-10).
ISENTROPIC_REL = 1e-7
# Closed cell with a very large wall film coefficient: isothermal up to the finite exchange
# (temperature lag ~ 1e-3 of the compression heating at 3e5 W/(m^2 K)).
ISOTHERMAL_REL = 2e-3
# Mass conservation across cells, ports, leaks and booster at rtol 1e-8: the mass rows sum to zero
# by construction, so the total drifts only by the integrator's error on the sum.
MASS_CONSERVATION_REL = 1e-8
# Spec §8 closed forms, the bound: ideal pump-down law and isothermal ultimate pressure
# within 1 %.
PUMPDOWN_LAW_REL = 0.01
ULTIMATE_PRESSURE_REL = 0.01
# Fast path (cycle-averaged maps, monotone cubic in log p) against the full model: time to target
# and mean current within 2 % (map interpolation and the quasi-steady assumption).
FAST_PATH_REL = 0.02
# The pump-down's default tolerances (pumpsim.tolerances.PUMPDOWN_RTOL/ATOL) against a run 100x
# tighter: the full path's own integration error must stay an order of magnitude below the 2 %
# fast-vs-full agreement it is checked against (observed on a 1 L booster: 4.4e-4 in time to
# target, 5.3e-4 on the booster pressure curve).
PUMPDOWN_CONVERGED_REL = 2e-3
# Target crossing located by Illinois root finding to 1e-10 s: the booster pressure at the located
# time is the target to ~1e-9 relative (pressure rate x time tolerance).
TARGET_LOCATED_REL = 1e-8
# Reed valve: the stop is an event, the lift is set to x_max exactly there (rounding only);
# the opening force at a located opening is zero to the event time tolerance (1e-10 s x force
# rate), relative to the preload (the exhaust pressure there to the same over the valve's area:
# 2.5e-3 Pa, 2.4e-8 relative; a fixed 1e-8 held while the port was isothermal, whose pressure
# rises 1/gamma as fast as the adiabatic port's at the same inflow).
REED_STOP_REL = 1e-12
REED_FORCE_REL = 1e-6

# Detectors (tests/unit/pumpsim/test_detectors.py). A correct null distribution fails a KS test of
# its p-values at 0.1 % once in a thousand seeds (the seeds are fixed, so the test is repeatable).
NULL_KS_P = 1e-3
# The high-frequency noise estimate is a median of ~400 periodogram ordinates (exponential): its
# relative spread is ~3.6 %, so 10 % is ~2.8 standard deviations.
HF_SIGMA_REL = 0.1
# A 30 Hz sine as large as the noise over 4000 samples: the noise-level test must reject it at a
# level no null record reaches by chance in this suite.
STRUCTURE_P = 1e-6
# RMS of a non-shaft line (0.3) on unit noise, 6000 samples: the variance estimate's spread
# (sqrt(2/n) ~ 0.018) gives ~0.03 on the RMS; 0.12 is four of those.
SYSTEMATIC_RMS_ABS = 0.12
# The synchronous speed scan's refined grid: the phase drift it leaves over the record [rad].
SPEED_SCAN_DRIFT_RAD = 0.1

# Integrator settings of the contact-model tests (tests/integration/test_contact_model.py), each
# chosen so the integrator's error is far below what the test compares:
# Model 1 vs Model 2: the models differ by ~penetration/L ~ 1e-4; rtol 1e-7 keeps Model 1's error 1e3 below.
MODEL1_VS_2_RTOL, MODEL1_VS_2_ATOL = 1e-7, 1e-10
# Closed forms of a linear contact (damped oscillator on the slot bottom, ~1e-3 bounds): 1e-8.
CONTACT_CLOSED_FORM_RTOL, CONTACT_CLOSED_FORM_ATOL = 1e-8, 1e-12
# Energy balances and crossing times asserted to ~1e-6: integrate ~1e-9..1e-10 (positions ~1e-5 m
# of penetration, so atol 1e-13..1e-14 m).
CONTACT_BALANCE_RTOL, CONTACT_BALANCE_ATOL = 1e-9, 1e-13
CONTACT_ENERGY_RTOL, CONTACT_ENERGY_ATOL = 1e-10, 1e-14
# Energy drift must shrink with the tolerance: two rtols two decades apart, atol = rtol x 1e-4 m.
CONTACT_DRIFT_RTOLS, CONTACT_DRIFT_ATOL_PER_RTOL = (1e-8, 1e-10), 1e-4
# Behaviour tests (events, completion, statistics) where no accuracy is asserted: the report's
# Table 13 setting.
CONTACT_BEHAVIOUR_RTOL, CONTACT_BEHAVIOUR_ATOL = 1e-6, 1e-10
# CVODES vs IDAS: both at 1e-8, compared against INTEGRATOR_CROSS_REL (1e-4 of RMS torque).
CONTACT_CROSS_RTOL = 1e-8
# The sensor low-pass's first-order-hold discretisation is second order: halving dt divides the
# error on a sine by 4 in the limit; at omega dt = 0.25 the next term shifts the ratio by ~10 %,
# so a ratio above 4 / 1.25 = 3.2 confirms the order (a zero-order hold gives 2).
LAG_FOH_ORDER_SLACK = 1.25
# The lagged model (4 points per sample interval) against a 16 x finer filter, RMS over the RMS of
# the lag's effect: measured 0.025 on the 3-vane ellipse (halving per doubling: 0.10, 0.054, 0.025,
# 0.012 at 1, 2, 4, 8 points); 0.05 leaves 2 x and fails at 2 points or fewer.
LAG_MODEL_SUBSAMPLE_REL = 0.05
# A size quoted as "~N" in the README or an example's comment is rounded to whole units (~18 for
# 17.8): within 5 % of what the model computes (the old ~9 and ~13 cm^3/rev were 50 % and 27 % off).
QUOTED_FIGURE_REL = 0.05

# reversal-aware cost (pumpsim/identification/reversals.py): the step signature of a cubic is
# exact up to rounding of O(1) values summed over five samples
STEP_SIGNATURE_ABS = 1e-12
# the robust (MAD of first differences) noise sigma on 20,000 Gaussian samples: its standard
# error is ~1.1 % (MAD efficiency 37 %); 5 % is > 4 standard errors
ROBUST_SIGMA_REL = 0.05
# the reversal-aware cost's theta0 profile (n ln RSS between 0.2 mrad neighbours) is a smooth
# parabola: its steps change linearly, their second differences below one unit of chi-square
# (the all-samples cost's steps jump by hundreds)
PROFILE_SMOOTH_CHI2 = 1.0
# the kurtosis test's level in the F8 test (diagnose's UNEXPLAINED_ALPHA): the moved-reversal
# outliers reject far below it (p ~ 1e-25); Gaussian samples pass it 99 % of the time
KURTOSIS_SITUATION_P = 0.01
# diagnose.homogeneity under its null (2,000 draws of white noise): the rejection rate at 5 % has a
# binomial standard error of 0.49 %; 2 % is > 4 of them. The statistic's mean (dof 6, variance
# 12 per draw) has a standard error of 0.08; 0.5 is > 6 of them.
HOMOGENEITY_RATE_ABS = 0.02
HOMOGENEITY_MEAN_ABS = 0.5
# The speed column's trend (data.speed_trend) on a record that starts mid-run-up (speed 14 % low at
# the start, constant after 21 % of the record, 97 revolutions, noise-free column): the largest
# speed error it leaves, relative. The BIC-chosen Legendre degree (18-19) leaves 4e-4; the old cap of
# degree 6 left 7e-3, i.e. a torque error of ~1.4 % (friction torque ~ omega^2), 0.7 noise sigma at
# SNR 10. 1e-3 keeps the torque error below 0.1 sigma there.
RUNUP_TREND_REL = 1e-3
# diagnostics.broadband_sigma against the noise's own standard deviation: AR(1) noise with phi 0.85
# over 8000 samples has ~8000 x 0.15 / 1.85 = 650 effective samples, so its sample sd scatters by
# ~2.8 %; 10 % is 3.6 of those (white noise: 1.4 %, seven of them).
BROADBAND_SIGMA_REL = 0.10


# interval-average Jacobian columns of geometric defects (problem._interval_columns), 8 points per
# sample interval, against 64: their cosine at least this much above the exact pointwise column's
# (measured on the tilted3 oval: 0.37 / 0.9996 against 0.06 / 0.9996 -- the 8-point difference
# resolves a reversal's motion to 1/8 interval only, a noisy but unbiased estimate)
INTERVAL_COS_GAIN = 0.2
# a fit in the truth's valley of a noisy record leaves the noise: RMS / sigma below this (1.008 at the
# grid's SNR-5 tilted3 oval; n = 1001 samples, so sqrt(1 - 6/n) +- 2 % for noise alone); one stalled on
# the reversal staircase leaves 1.5-2.4 (a reversal a sample off costs a whole Coulomb step)
INTERVAL_VALLEY_RMS = 1.03
# the geometric columns from the exact derivatives where the torque is smooth on the sample scale
# (identification/interval.py) against the sub-sample runs on every sample: their difference over
# the column's norm. Measured 1e-7 - 5e-6 on the 4-vane ellipse's k = 2 and k = 4 ovals at 10 and
# 20 kHz and 2.4e-6 on the tilted3 oval (the smooth formula's O(h^4) remainder); a missed step or
# narrow transition costs far more (one such sample on the concentric rig: 5x the column's norm)
INTERVAL_SMOOTH_REL = 1e-4

# Dataset.mean_speed: the stretch of whole revolutions ends within one sample of the last whole
# turn, so a ripple eps can bias it by at most eps x (one sample's share of the stretch)
WHOLE_REVOLUTION_SAMPLES = 1.0
# noise_sigma(order=3): a MAD estimate of sigma has relative standard error ~1.1 / sqrt(n) on independent
# values, more on third differences (neighbours share samples): 1.7 / sqrt(n), at 5 standard errors
MAD_SIGMA_SE = 1.7
MAD_SIGMA_Z = 5.0
# A hose-limited pump-down (choked hose, booster 20 cm^3, manifold < 0.5 of the booster) against
# p_b = p0 exp(-t/tau): the pump's pulsation and the start-up transient the measured interval
# skips leave ~0.1 %; 1 % is the spec's bound for its pump-down closed forms.
HOSE_TIME_CONSTANT_REL = 0.01
# Located current peak against the largest sample of a run at 400 kHz output, both at rtol 1e-7:
# that sample misses the peak by ~(dt/tau)^2 / 2 ~ 2e-5 at most (dt 2.5 us, L/R 0.4 ms; measured
# 6e-7), the runs' integration errors are ~1e-7; 2e-5 is 100x below the 2 kHz sample's miss (0.2 %).
PEAK_CURRENT_REL = 2e-5
# Quasi-static ultimate pressure marched on this many angles per revolution: a window opens or
# closes up to one step late, an error ~1/n (measured on the EVP geometry: 7252, 7208, 7202 Pa at
# 1000, 4000, 16000 angles), 1e-3 at 4000 -- a tenth of ULTIMATE_PRESSURE_REL.
QUASI_STATIC_GRID = 4000
# Pump-down at the default tolerances against 100x tighter, over the range of gas.heat_transfer
# (1 L booster): measured 3e-4 (h = 2e4), 6e-4 (2e5), 5e-4 (2e6) in time to target; 1e-3 is the
# issue's bound for the whole range.
PUMPDOWN_RANGE_REL = 1e-3
# Geometry table (pneumatics.geometry_table) against the compiled geometry: its slope (only the
# Jacobian's) at random angles, measured 1.5e-8 of each quantity's largest slope on the EVP
# circle; 1e-6 leaves room for other housings and is still far below what moves a Newton
# iteration.
TABLE_SLOPE_REL = 1e-6
# The tabulated right-hand side and Jacobian with the exact geometry put in: the same operations
# as the exact kernels in another order (measured 2e-13 relative).
TABLE_KERNEL_REL = 1e-10
# Pump-down figures (time to target 95 kPa, energy, mean and peak current) and reed-valve states
# with the table against the exact kernel, both at rtol 1e-8: the table's own error (~1e-11) is
# far below; what remains is the integration's error, which falls with rtol (measured 8e-8 on the
# circle, 2e-8 on the ellipse; up to 5e-6 at rtol 1e-7, ~1e-4 at the default 1e-4).
TABLE_FIGURE_REL = 1e-6
# Reed events (seat, stop, opening) located with the table against the exact kernel at rtol 1e-8
# (s): the location tolerance is 1e-10 s, the integration's error on the crossing ~1e-8 s.
TABLE_EVENT_ABS = 1e-7
# A voltage-driven run (a bench log's supply, dipping 13.5 -> 10 V in one sample) on the direct
# driver with the geometry table against CasADi's plugin on the exact geometry, both at rtol 1e-8,
# sample by sample (booster pressure, current, speed; of each channel's range): measured 6e-8,
# 4e-7, 5e-7 -- each run's own integration error (the table's is ~1e-9); 1e-5 leaves room for
# other machines' step sequences; the step one sample late moves them by 1e-3, 0.15 and 1e-2.
DRIVE_CHANNEL_REL = 1e-5
# The bench-log fit's estimates with the geometry table against the exact geometry, in standard
# errors: the integration's noise at rtol 1e-6 moves the tight residual's minimum by up to ~0.15
# (5 s log, seeds 0-2; as far as an atol changed by 1e-9 of itself moves it), never the table.
FIT_SHIFT_SE = 0.25
