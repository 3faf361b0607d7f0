"""The runtime's numerical tolerances and solver defaults, each with its reason, in one place."""

# The position solve closes the tip contact to ~1e-16 m on ~1e-2 m lengths; a residual above this
# means it did not converge, which is reported, never used.
POSITION_TOL = 1e-10  # m
# Relative spread of the slot-wall forces between consistent contact-side sets beyond which they
# are different solutions (a friction paradox); the consistency test itself is at 1e-9
# (codegen.model.CONSISTENCY_TOL), so rounding never reaches this.
PARADOX_TOL = 1e-6
# Integrator defaults (simulate, the CLI, the Integrator): relative tolerance, and the absolute
# tolerance of positions [rad, m] (speeds: ATOL * omega_0 in the contact model, see
# contact.state_scale).
RTOL = 1e-8
ATOL = 1e-10
# Explicit RK4: fixed substep when --max-step is not given [s] (a contact transient at k = 1e5 N/m
# and a 1 g vane has a period ~0.6 ms; 1 us resolves it with RK4's stability margin).
RK_MAX_STEP = 1e-6
