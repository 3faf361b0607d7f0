"""Model 1 (spec §2): every vane has its own s_i, sdot_i and touches the housing and the slot bottom
through penalty contacts (report §5.5, Table 1).

Housing contact point C: for a sharp tip (rho = 0) the intersection of the vane centre line with the
housing; for rho > 0 the foot of the housing normal through the tip-arc centre P. Penetration
delta = rho - (P - C).n (> 0 is interference; for rho = 0 this is (B - C).(-n)), and its exact time
derivative by implicit differentiation of the equation that fixes C. The slot bottom pushes along +u
when s < 0. Given the contact forces, the vane equations are linear in (sddot, F1, F2) for each
contact-side set, exactly as in Model 2 with N replaced by sddot as the unknown.
"""
from __future__ import annotations

from types import SimpleNamespace

import casadi as ca

from pumpsim.model_spec import laws
from pumpsim.model_spec.outputs import CONTACT_VANE_OUTPUTS, VANE_OUTPUTS

from .builder import CASADI_OPS, Builder, BuiltModel, newton_omegadot, rotor_torque

RATE_COLUMNS = ("theta", "omega", "omegadot", "s", "sdot")  # what one vane's rates depend on


def contact_law(b, side, delta, delta_dot):
    """Force and stored energy of the configured law on one side (housing | bottom)."""
    law = b.st.housing_law if side == "housing" else b.st.bottom_law
    P = b.P
    k, e = P[f"contact.{side}.stiffness"], P[f"contact.{side}.exponent"]
    c, d = P[f"contact.{side}.damping"], P[f"contact.{side}.depth"]
    force = laws.contact_force(law, delta, delta_dot, k, e, c, d, P["vane.mass"], CASADI_OPS)
    dp = ca.fmax(delta, 0.0)
    if law == "linear":
        energy = 0.5 * k * dp**2
    elif law == "report-nonlinear":
        energy = k * dp**5 / 5
    else:  # hunt-crossley, impact: elastic part k d^e
        energy = k * ca.power(dp, e + 1) / (e + 1)
    return force, energy


def housing_contact(b, th, w, s, sd, phi) -> dict:
    """The housing contact of one vane at (theta, omega, s, sdot): housing parameter alpha (Newton on
    the equation that fixes C, as a function of (theta, s)), its rate, the penetration delta and its
    exact rate, C and n (rotor frame), and the Newton residual."""
    g = b.geometry()
    rho = g["rho"]
    a_s, th_s, s_s, ph_s = ca.SX.sym("a"), ca.SX.sym("th"), ca.SX.sym("s"), ca.SX.sym("ph")

    def geometry_at(th_, s_, ph_, a_):
        m = b.mech(phi=ph_, s=s_, **g)
        hs = b.housing(a_)
        C, n = b.to_rotor(th_, hs["C"]), b.to_rotor(th_, hs["n"])
        t = ca.vertcat(-n[1], n[0])
        on_centre_line = ca.dot(C - m["Ob"], m["w"])
        normal_foot = ca.dot(m["P"] - C, t)
        gap_eq = ca.if_else(rho > 0, normal_foot, on_centre_line)
        delta = rho - ca.dot(m["P"] - C, n)
        return m, C, n, gap_eq, delta

    _, _, _, gap_eq, delta_s = geometry_at(th_s, s_s, ph_s, a_s)
    base = b.mech(phi=phi, s=s, **g)
    alpha, res = b.newton_alpha(b.ray_guess(th, base["Ob"], base["u"]), gap_eq, [th, s, phi],
                                [th_s, s_s, ph_s], a_s)
    # exact delta-dot: alpha(theta, s) is implicit in gap_eq(theta, s, alpha) = 0
    q = ca.vertcat(th_s, s_s, a_s)
    dG = ca.jacobian(gap_eq, q)
    dD = ca.jacobian(delta_s, q)
    dfun = ca.Function("delta_terms", [th_s, s_s, ph_s, a_s, b.p], [delta_s, dG, dD])
    delta, dGv, dDv = dfun(th, s, phi, alpha, b.p)
    alphadot = -(dGv[0] * w + dGv[1] * sd) / dGv[2]
    delta_dot = dDv[0] * w + dDv[1] * sd + dDv[2] * alphadot
    _, C, n, _, _ = geometry_at(th, s, phi, alpha)
    return dict(alpha=alpha, alphadot=alphadot, delta=delta, delta_dot=delta_dot, C=C, n=n,
                residual=res)


def contact_vane(b, th, w, wd, s, sd, phi, factor, loads=None) -> dict:
    """One vane's penalty contacts, friction and the vane equations solved for (sddot, F1, F2).
    loads(alpha) -> (slide, lateral, tilt, rotor) generalised forces of further loads (gas
    pressure, spec §8) at housing parameter alpha, or None; the rotor's share is the vane's drive
    torque share minus the loads' moment on the rotor."""
    g = b.geometry()
    cp = housing_contact(b, th, w, s, sd, phi)
    alpha, delta, delta_dot, C, n = (cp[k] for k in ("alpha", "delta", "delta_dot", "C", "n"))
    N, e_h = contact_law(b, "housing", delta, delta_dot)
    Fb, e_b = contact_law(b, "bottom", -s, -sd)
    in_contact = delta > 0
    c_visc = ca.if_else(in_contact, b.P["effects.viscous_tip_friction"], 0.0)
    common = dict(theta=th, omega=w, omegadot=wd, phi=phi, s=s, sdot=sd, Cx=C[0], Cy=C[1],
                  nx=n[0], ny=n[1], N=N, Fb=Fb, c_visc=c_visc, **g)
    v_t = b.mech(**common)["tip_slip"]
    mu_h = factor * b.friction(v_t, "housing")
    mu_r = factor * b.friction(sd, "slot")  # a vane's material/finish: tip and slot
    common.update(mu_h=mu_h, mu_r=mu_r)
    gf = loads(alpha) if loads is not None else None
    best, n_cons, amb, final = b.solve_contact_sides(("sddot", "F1", "F2"), common,
                                                     extra=None if gf is None else gf[:3])
    share = final["torque_share"] if gf is None else final["torque_share"] - gf[3]
    outs = dict(sddot=best[0], normal=N, slot1=best[1], slot2=best[2], bottom=Fb, penetration=delta,
                penetration_rate=delta_dot, alpha=alpha, tip_slip=v_t, mu_housing=mu_h, mu_slot=mu_r,
                kinetic_energy=final["kinetic_energy"], potential_energy=e_h + e_b,
                torque_share=share, torque_slope=ca.jacobian(share, wd),
                n_consistent=n_cons, ambiguity=amb, position_residual=cp["residual"])
    # power of the tip and slot friction (and viscous tip friction), and of the penalty contacts
    # on the vane's surroundings (elastic storage + contact damping)
    outs["friction_power"] = (N * mu_h * v_t + c_visc * v_t * v_t
                              + mu_r * sd * (ca.fabs(best[1]) + ca.fabs(best[2])))
    outs["contact_power"] = N * delta_dot - Fb * sd
    outs["alphadot"] = cp["alphadot"]
    return outs


def vane_functions(b) -> dict:
    """One vane: every output (vane_contact), the lean rates the ODEs need, their Jacobians."""
    th, w, wd, s, sd, phi, factor = (ca.SX.sym(n) for n in
                                     ("theta", "omega", "omegadot", "s", "sdot", "phi", "factor"))
    outs = contact_vane(b, th, w, wd, s, sd, phi, factor)
    args = [th, w, wd, s, sd, phi, factor, b.p]
    names = ["theta", "omega", "omegadot", "s", "sdot", "phi", "factor", "p"]

    def fn(name, out_names, exprs):  # an SX function keeps only what its outputs need
        return ca.Function(name, args, exprs, names, out_names, {"cse": True})

    q = ca.vertcat(*[dict(theta=th, omega=w, omegadot=wd, s=s, sdot=sd)[c] for c in RATE_COLUMNS])
    sdd, share = outs["sddot"], outs["torque_share"]
    return {
        "vane_contact": fn("vane_contact", list(CONTACT_VANE_OUTPUTS), [outs[k] for k in CONTACT_VANE_OUTPUTS]),
        # lean right-hand sides: the prescribed-speed ODE needs sddot only, the torque drive
        # also the vane's drive-torque share and its slope for the Newton solve on omegadot
        "vane_accel": fn("vane_accel", ["sddot"], [sdd]),
        "vane_rates": fn("vane_rates", ["sddot", "torque_share", "torque_slope"],
                         [sdd, share, outs["torque_slope"]]),
        # and their derivatives (one vane, scalar AD: a few times the cost of the vane itself)
        "vane_accel_jac": fn("vane_accel_jac", ["d_sddot"], [ca.jacobian(sdd, q)]),
        "vane_rates_jac": fn("vane_rates_jac", ["d_rates"], [ca.jacobian(ca.vertcat(sdd, share), q)]),
    }


def build_contact_model(structure) -> BuiltModel:
    """Every exported CasADi function of a contact-model (Model 1) variant."""
    b = Builder(structure)
    fns = build_contact_functions(b)
    fns["housing_curve"] = b.housing_function()
    return BuiltModel(structure, b.params, fns)


def build_contact_functions(b) -> dict:
    N = b.st.vanes
    vf = vane_functions(b)
    p = ca.MX.sym("p", len(b.params))
    th, w, wd, tau = (ca.MX.sym(n) for n in ("theta", "omega", "omegadot", "torque"))
    s, sd = ca.MX.sym("s", N), ca.MX.sym("sdot", N)
    phis, facs = b.slot_angles(p), b.factors(p)
    Ir, tb = b.pget(p, "rotor.inertia"), b.pget(p, "operation.bearing_torque")
    i_share = CONTACT_VANE_OUTPUTS.index("torque_share")

    def vanes(name, th_, w_, wd_, s_, sd_):  # one row per output, one column per vane
        return vf[name].map(N)(th_, w_, wd_, s_.T, sd_.T, phis, facs, p)

    def forward_omegadot(th_, w_, s_, sd_):
        def required(wdk):
            _, share, slope = vanes("vane_rates", th_, w_, wdk, s_, sd_)
            return rotor_torque(Ir, tb, wdk, share), slope

        return newton_omegadot(required, Ir, tau)

    o = vanes("vane_contact", th, w, wd, s, sd)
    dyn = ca.Function("contact_dynamics", [th, w, wd, s, sd, p], [rotor_torque(Ir, tb, wd, o[i_share]), *o],
                      ["theta", "omega", "omegadot", "s", "sdot", "p"], ["torque", *CONTACT_VANE_OUTPUTS])
    wd_f = forward_omegadot(th, w, s, sd)
    of = vanes("vane_contact", th, w, wd_f, s, sd)
    fwd = ca.Function("contact_forward", [th, w, tau, s, sd, p],
                      [wd_f, rotor_torque(Ir, tb, wd_f, of[i_share]) - tau, *of],
                      ["theta", "omega", "torque", "s", "sdot", "p"],
                      ["omegadot", "torque_residual", *CONTACT_VANE_OUTPUTS])
    ctx = SimpleNamespace(N=N, p=p, wd=wd, tau=tau, Ir=Ir, vanes=vanes, forward_omegadot=forward_omegadot)
    # Model 2 state, for starting on the housing
    oc = b.vane_constrained().map(N)(th, w, 0.0, phis, facs, p)
    cstate = ca.Function("constrained_state", [th, w, p],
                         [oc[VANE_OUTPUTS.index("s")].T, oc[VANE_OUTPUTS.index("sdot")].T,
                          oc[VANE_OUTPUTS.index("normal")].T],
                         ["theta", "omega", "p"], ["s", "sdot", "normal"])
    return {f.name(): f for f in (dyn, fwd, *_odes(ctx), cstate)}


def _odes(c):
    """ODEs for the integrator, x = (theta, omega, s_0.., sdot_0..), and their Jacobians in x and
    in the drive (omegadot or torque), assembled from the per-vane derivatives: vane i's
    acceleration depends on (theta, omega, omegadot, s_i, sdot_i) only (RATE_COLUMNS)."""
    N, p, wd, tau, Ir, vanes = c.N, c.p, c.wd, c.tau, c.Ir, c.vanes
    nx = 2 + 2 * N
    x = ca.MX.sym("x", nx)
    xs, xsd = x[2:2 + N], x[2 + N:]
    nr = len(RATE_COLUMNS)

    def state_column(col, i):  # the state behind vane i's RATE_COLUMNS entry col
        return {"theta": 0, "omega": 1, "s": 2 + i, "sdot": 2 + N + i}[col]

    def partials(D, row, i):  # vane i's derivatives of output `row` by column name
        return {col: D[row, nr * i + k] for k, col in enumerate(RATE_COLUMNS)}

    kinematic = {(0, 1): 1.0, **{(2 + i, 2 + N + i): 1.0 for i in range(N)}}  # theta' = omega, s' = sdot

    sdd = vanes("vane_accel", x[0], x[1], wd, xs, xsd)
    ode_speed = ca.Function("ode_speed", [x, wd, p], [ca.vertcat(x[1], wd, xsd, sdd.T)],
                            ["x", "omegadot", "p"], ["xdot"])
    D = vanes("vane_accel_jac", x[0], x[1], wd, xs, xsd)  # 1 x (nr N)
    jx, jd = dict(kinematic), {1: 1.0}
    for i in range(N):
        d = partials(D, 0, i)
        jd[2 + N + i] = d.pop("omegadot")
        jx.update({(2 + N + i, state_column(col, i)): v for col, v in d.items()})
    ode_speed_jac = ca.Function("ode_speed_jac", [x, wd, p], [_sparse(nx, nx, jx), _sparse(nx, 1, jd)],
                                ["x", "omegadot", "p"], ["jac_xdot_x", "jac_xdot_omegadot"])

    wd_t = c.forward_omegadot(x[0], x[1], xs, xsd)
    sdd_t = vanes("vane_rates", x[0], x[1], wd_t, xs, xsd)[0]
    ode_torque = ca.Function("ode_torque", [x, tau, p], [ca.vertcat(x[1], wd_t, xsd, sdd_t.T)],
                             ["x", "torque", "p"], ["xdot"])
    # omegadot(x, torque) is implicit in the rotor equation R = rotor_torque(wd, share) - torque
    # = 0: d wd = -(dR/dx dx - d torque) / (dR/d wd); every vane's row picks up d sddot_i/d wd d wd
    D = vanes("vane_rates_jac", x[0], x[1], wd_t, xs, xsd)  # 2 x (nr N): rows sddot, share
    accel = [partials(D, 0, i) for i in range(N)]
    share = [partials(D, 1, i) for i in range(N)]
    R_wd = Ir + sum(sh["omegadot"] for sh in share)
    dW = {}  # d omegadot / d x_j
    for i, sh in enumerate(share):
        for col, v in sh.items():
            if col != "omegadot":
                j = state_column(col, i)
                dW[j] = dW.get(j, 0.0) - v / R_wd
    jx, jd = dict(kinematic), {1: 1.0 / R_wd}
    jx.update({(1, j): v for j, v in dW.items()})
    for i, a in enumerate(accel):
        r = 2 + N + i
        jd[r] = a["omegadot"] / R_wd
        jx.update({(r, j): a["omegadot"] * v for j, v in dW.items()})
        for col, v in a.items():
            if col != "omegadot":
                jx[(r, state_column(col, i))] += v
    ode_torque_jac = ca.Function("ode_torque_jac", [x, tau, p], [_sparse(nx, nx, jx), _sparse(nx, 1, jd)],
                                 ["x", "torque", "p"], ["jac_xdot_x", "jac_xdot_torque"])
    return ode_speed, ode_speed_jac, ode_torque, ode_torque_jac


def _sparse(nrow, ncol, entries):
    """A sparse MX matrix from {(row, col): value} (or {row: value} for a column): the pattern
    CVODES factorises."""
    cells = {(k, 0) if isinstance(k, int) else k: v for k, v in entries.items()}
    keys = sorted(cells, key=lambda rc: (rc[1], rc[0]))  # column-major, as CasADi stores them
    sp = ca.Sparsity.triplet(nrow, ncol, [r for r, _ in keys], [c for _, c in keys])
    return ca.MX(sp, ca.vertcat(*[ca.MX(cells[k]) if isinstance(cells[k], float) else cells[k] for k in keys]))
