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

import casadi as ca

from pumpsim import laws

from .model import CASADI_OPS

CONTACT_VANE_OUTPUTS = (
    "sddot", "normal", "slot1", "slot2", "bottom", "penetration", "penetration_rate", "alpha",
    "tip_slip", "mu_housing", "mu_slot", "kinetic_energy", "potential_energy", "torque_share",
    "torque_slope", "n_consistent", "ambiguity", "position_residual",
)


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


def vane_contact(b) -> ca.Function:
    th, w, wd, s, sd, phi, factor = (ca.SX.sym(n) for n in
                                     ("theta", "omega", "omegadot", "s", "sdot", "phi", "factor"))
    g = b.geometry()
    rho = g["rho"]
    # housing point: Newton on the equation that fixes C, as a function of (theta, s)
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

    m0, _, _, gap_eq, delta_s = geometry_at(th_s, s_s, ph_s, a_s)
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

    N, e_h = contact_law(b, "housing", delta, delta_dot)
    Fb, e_b = contact_law(b, "bottom", -s, -sd)
    in_contact = delta > 0
    common = dict(theta=th, omega=w, omegadot=wd, phi=phi, s=s, sdot=sd, Cx=C[0], Cy=C[1],
                  nx=n[0], ny=n[1], N=N, Fb=Fb,
                  c_visc=ca.if_else(in_contact, b.P["effects.viscous_tip_friction"], 0.0), **g)
    v_t = b.mech(**common)["tip_slip"]
    mu_h = factor * b.friction(v_t, "housing")
    mu_r = b.friction(sd, "slot")
    common.update(mu_h=mu_h, mu_r=mu_r)
    best, n_cons, amb, final = b.solve_contact_sides(("sddot", "F1", "F2"), common)
    outs = dict(sddot=best[0], normal=N, slot1=best[1], slot2=best[2], bottom=Fb, penetration=delta,
                penetration_rate=delta_dot, alpha=alpha, tip_slip=v_t, mu_housing=mu_h, mu_slot=mu_r,
                kinetic_energy=final["kinetic_energy"], potential_energy=e_h + e_b,
                torque_share=final["torque_share"], torque_slope=ca.jacobian(final["torque_share"], wd),
                n_consistent=n_cons, ambiguity=amb, position_residual=res)
    return ca.Function("vane_contact", [th, w, wd, s, sd, phi, factor, b.p],
                       [outs[k] for k in CONTACT_VANE_OUTPUTS],
                       ["theta", "omega", "omegadot", "s", "sdot", "phi", "factor", "p"],
                       list(CONTACT_VANE_OUTPUTS), {"cse": True})


def build_contact_functions(b) -> dict:
    N = b.st.vanes
    vmap = vane_contact(b).map(N)
    p = ca.MX.sym("p", len(b.params))
    th, w, wd, tau = (ca.MX.sym(n) for n in ("theta", "omega", "omegadot", "torque"))
    s, sd = ca.MX.sym("s", N), ca.MX.sym("sdot", N)
    phis, facs = b.slot_angles(p), b.factors(p)
    Ir, tb = b.pget(p, "rotor.inertia"), b.pget(p, "operation.bearing_torque")
    i_share = CONTACT_VANE_OUTPUTS.index("torque_share")
    i_slope = CONTACT_VANE_OUTPUTS.index("torque_slope")
    i_sdd = CONTACT_VANE_OUTPUTS.index("sddot")

    def evaluate(th_, w_, wd_, s_, sd_):
        o = vmap(th_, w_, wd_, s_.T, sd_.T, phis, facs, p)
        return Ir * wd_ + tb + ca.sum2(o[i_share]), o

    tq, o = evaluate(th, w, wd, s, sd)
    dyn = ca.Function("contact_dynamics", [th, w, wd, s, sd, p], [tq, *o],
                      ["theta", "omega", "omegadot", "s", "sdot", "p"], ["torque", *CONTACT_VANE_OUTPUTS])
    # torque drive: Newton on omegadot (piecewise affine, slope from the vanes)
    wdk = ca.MX(0.0)
    for _ in range(4):
        rt, ok = evaluate(th, w, wdk, s, sd)
        wdk = wdk - (rt - tau) / (Ir + ca.sum2(ok[i_slope]))
    rt, of = evaluate(th, w, wdk, s, sd)
    fwd = ca.Function("contact_forward", [th, w, tau, s, sd, p], [wdk, rt - tau, *of],
                      ["theta", "omega", "torque", "s", "sdot", "p"],
                      ["omegadot", "torque_residual", *CONTACT_VANE_OUTPUTS])
    x = ca.MX.sym("x", 2 + 2 * N)  # theta, omega, s_0.., sdot_0..
    xs, xsd = x[2:2 + N], x[2 + N:]
    o_sp = evaluate(x[0], x[1], wd, xs, xsd)[1]
    ode_speed = ca.Function("ode_speed", [x, wd, p],
                            [ca.vertcat(x[1], wd, xsd, o_sp[i_sdd].T)], ["x", "omegadot", "p"], ["xdot"])
    wd_t = fwd(x[0], x[1], tau, xs, xsd, p)[0]
    o_tq = evaluate(x[0], x[1], wd_t, xs, xsd)[1]
    ode_torque = ca.Function("ode_torque", [x, tau, p],
                             [ca.vertcat(x[1], wd_t, xsd, o_tq[i_sdd].T)], ["x", "torque", "p"], ["xdot"])
    # Model 2 state, for starting on the housing
    vc = b.vane_constrained().map(N)
    from .model import VANE_OUTPUTS

    oc = vc(th, w, 0.0, phis, facs, p)
    cstate = ca.Function("constrained_state", [th, w, p],
                         [oc[VANE_OUTPUTS.index("s")].T, oc[VANE_OUTPUTS.index("sdot")].T,
                          oc[VANE_OUTPUTS.index("normal")].T],
                         ["theta", "omega", "p"], ["s", "sdot", "normal"])
    return {f.name(): f for f in (dyn, fwd, ode_speed, ode_torque, cstate)}

