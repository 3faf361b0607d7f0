"""The runtime's numerical tolerances and solver defaults, each with its reason, in one place."""

# The position solve closes the tip contact to ~1e-16 m on ~1e-2 m lengths; a residual above this
# means it did not converge, which is reported, never used.
POSITION_TOL = 1e-10  # m
# Relative spread of the slot-wall forces between consistent contact-side sets beyond which they
# are different solutions (a friction paradox); the consistency test itself is at 1e-9
# (codegen.builder.CONSISTENCY_TOL), so rounding never reaches this.
PARADOX_TOL = 1e-6
# Integrator defaults (simulate, the CLI, the Integrator): relative tolerance, and the absolute
# tolerance of positions [rad, m] (speeds: ATOL * omega_0 in the contact model, see
# contact.state_scale).
RTOL = 1e-8
ATOL = 1e-10
# Identification: a column-scaled Jacobian whose condition number exceeds this has a near-null
# direction (J'J singular to working precision after squaring: 1e14 of 1e16): the parameters along it
# are not identifiable, and Gauss-Newton stops rather than take a step along it.
SINGULAR_COND = 1e7
# A fit is at its minimum when the Gauss-Newton step from its last point is below this many of each
# parameter's standard errors: the bench-log fit's full-model steps stop there, and a Gauss-Newton
# fit that reaches its iteration limit still creeping (a few 1e-6 of the RMS per step) is converged
# when its remaining step is: what is left moves no estimate by a fifth of its uncertainty.
STEP_SE = 0.2
# A fitted parameter whose change by its own size (or by 1 for angles and offsets) moves the model
# by less than this share of its norm does not act on the data at all (rounding of the kernel is ~1e-15).
NO_EFFECT_REL = 1e-8
# Transient identification integrates the speed with CVODES sample by sample; its sensitivities
# must be far more accurate than the speed noise (~1e-2 rad/s on ~1e2 rad/s) for the Gauss-Newton
# steps and the standard errors to be the data's, not the integrator's.
TRANSIENT_FIT_RTOL = 1e-9
TRANSIENT_FIT_ATOL = 1e-11
# Figures: two vanes' curves closer than IDENTICAL_RTOL of the panel's range are drawn as one (the
# vanes of a concentric pump differ by rounding, ~1e-12); a torque ripple below FLAT_RTOL of the
# mean torque is rounding, not physics (a concentric rig's ripple is ~1e-16 of it).
IDENTICAL_RTOL = 1e-7
FLAT_RTOL = 1e-9
# Explicit RK4: fixed substep when --max-step is not given [s] (a contact transient at k = 1e5 N/m
# and a 1 g vane has a period ~0.6 ms; 1 us resolves it with RK4's stability margin).
RK_MAX_STEP = 1e-6
# Design studies: an output whose spread over the designs is below CONSTANT_REL of its size plus
# CONSTANT_ABS (by unit) is the round-off of a constant (the torque ripple of a concentric rig is
# ~1e-16 N m): the report shows it as a constant and Sobol' analysis skips it.
DESIGN_CONSTANT_REL = 1e-9
DESIGN_CONSTANT_ABS = {"N·m": 1e-12, "W": 1e-9, "N": 1e-9, "m": 1e-12, "Pa·m/s": 1e-6}
# Contact-model study: the last two simulated revolutions' torque may differ by this share of its
# peak for the last one to count as the periodic steady state. Measured from the in-contact start:
# the ellipse example is at 2.5e-6 after 6 revolutions; the concentric rig (k = 5e4 N/m) decays
# slowly (ratio ~0.92 per revolution): 3.5e-3 after 6, 5e-4 after 30 -- a change per revolution
# bounds the remaining transient only up to 1/(1 - ratio), so on the rig ~0.5 % may remain.
CONTACT_PERIODIC_REL = 1e-3
# Model 1 with gas (pumpsim.pneumatics.contact.integrate): the vanes' penetration (~1e-7..1e-5 m) sits
# on s ~ 5e-3 m, so the relative tolerance decides the contact force's accuracy: rtol 1e-7 puts
# ~5e-10 m on s (< 1e-3 of a 1 um penetration); atol relative to each state's nominal size
# (state_scale: vane positions 1e-3 x vane length).
CONTACT_GAS_RTOL, CONTACT_GAS_ATOL = 1e-7, 1e-6
# Solver study (pumpsim.solver_study): a row that names no tolerance runs at the report's Table 13 setting
# (BDF at rtol 1e-6), against a reference at the runtime defaults RTOL/ATOL above.
SOLVER_STUDY_RTOL, SOLVER_STUDY_ATOL = 1e-6, 1e-10
# Gas model (pumpsim.pneumatics): states scaled to their starting size (atol relative to it).
# GAS_*: single runs and periodic steady states (the mass and energy budgets close far below the
# tests' bounds); PUMPDOWN_*: thousands of revolutions, converged to ~5e-4 in the time to target
# (docs/explanation/gas-model.md, Tolerances; atol governs the small charges and matters most).
GAS_RTOL, GAS_ATOL = 1e-7, 1e-9
PUMPDOWN_RTOL, PUMPDOWN_ATOL = 1e-4, 1e-5
# Model 1 with gas (`pumpdown --model contact`) keeps 1e-5: rtol sets the error on the vane
# positions s_i (~5e-3 m), and 1e-4 would allow ~5e-7 m against ~1 um penetrations.
CONTACT_PUMPDOWN_RTOL, CONTACT_PUMPDOWN_ATOL = 1e-5, 1e-5
# Bench-log fits (pumpsim.identification.pumpdown_fit): the Jacobian is a difference of two runs,
# each with its own integration error; 1e-6 is the loosest rtol whose differences and estimates stay
# within a fraction of a standard error of a tight fit (docs/explanation/bench-log.md, Tolerances).
BENCH_FIT_RTOL, BENCH_FIT_ATOL = 1e-6, 1e-7
# A negative housing reaction within this share of the largest is rounding (a vane at rest has
# ~1e-15 N), not a lift-off
LIFT_OFF_ROUNDING_REL = 1e-9
