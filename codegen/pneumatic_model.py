"""The pneumatic pump (spec §8) in CasADi: Model 2 mechanics with gas cells, ports, valves, leaks,
booster and DC motor, for `codegen.build`.

State x (STATE_NAMES): theta, omega, current, cell masses m_i, cell internal energies U_i, inlet
manifold mass, exhaust-port mass, booster mass, inlet-manifold and exhaust-port internal energies,
reed lift and lift rate. Cells, manifold and exhaust port carry (m, U): mass and energy balances
are then sums of flows, each carrying its upstream stagnation enthalpy, so mass is conserved to
rounding by construction and to the integrator's tolerance in time. Manifold and exhaust port are
adiabatic (their vanishing-volume limit is the network of openings in series: no wall there); the
booster is isothermal at gas.temperature. Quadratures (QUAD_NAMES) accumulate the energy and mass
budgets.

Drive (operation.motor): 0 constant speed (omega is a state with zero rate, the torque is the
inverse dynamics), 1 brushed DC motor: V = R i + L di/dt + k omega and
k i - tau_friction - I_m omegadot = tau_shaft(omegadot), solved for omegadot by Newton steps on the
piecewise-affine required torque (as Model 2's forward dynamics).

Exported: cell_geometry, orifice_flow, pump_rhs (xdot, qdot), pump_rhs_jac (d xdot/dx, the exact
Jacobian CVODES is given), pump_outputs.
"""
from __future__ import annotations

import math

import casadi as ca

from pumpsim.model_spec.parameters import pneumatic_layout

from . import gas
from .cells import CellGeometry
from .housing import TWO_PI
from .builder import Builder, BuiltModel

MOTOR_FRICTION_SPEED = 0.5  # rad/s: motor friction torque = friction * tanh(omega / this)
# Newton steps on omegadot: the required torque is affine in omegadot on a contact-side branch, so
# the first step from 0 is exact unless the branch changes; the second corrects that case. The
# residual is returned (motor_residual) and checked by the runtime.
MOTOR_NEWTON_ITERATIONS = 2


# the manifold's and the exhaust port's internal energies: in every state layout the two states
# before the reed's two (state_names here and in pneumatic_contact_model)
PLENUM_ENERGIES = ("inlet_energy", "exhaust_energy")


def state_names(N):
    return (["theta", "omega", "current"] + [f"mass_{i}" for i in range(N)]
            + [f"energy_{i}" for i in range(N)]
            + ["inlet_mass", "exhaust_mass", "booster_mass"] + list(PLENUM_ENERGIES)
            + ["reed_lift", "reed_rate"])


def plenum_state(x, N):
    """(m_in, m_ex, m_b, U_in, U_ex) of a state vector in either layout."""
    nx = x.size1()
    return (*(x[3 + 2 * N + k] for k in range(3)), x[nx - 4], x[nx - 3])


QUAD_NAMES = ("electrical_energy", "shaft_work", "gas_work", "friction_work", "copper_loss",
              "motor_friction_work", "valve_damping_work", "atmosphere_mass")

# vane_geometry's rows: housing point and normal (rotor frame), ds/dtheta, d2s/dtheta2, and the
# coefficients of (p_lead, p_trail, p_slot) in the gas loads (slide, lateral, tilt, rotor)
VANE_GEOMETRY = ("Cx", "Cy", "nx", "ny", "ds", "d2s", *(f"load_{k}" for k in range(12)))
VANE_DYN_OUTPUTS = ("torque_share", "torque_slope", "normal", "slot1", "slot2", "n_consistent",
                    "friction_power", "load_power", "sdot", "kinetic_energy", "tip_slip", "mu_housing",
                    "mu_slot", "ambiguity")


class GasBuilder(Builder):
    def __init__(self, structure):
        super().__init__(structure, pneumatic_layout(structure))
        self.geo = CellGeometry(self)

    def factors(self, p):
        idx = {q.name: i for i, q in enumerate(self.params)}
        return ca.horzcat(*[p[idx[f"effects.vane_friction_factor.{i}"]] for i in range(self.st.vanes)])

    # -- per vane ------------------------------------------------------------------------------
    def vane_kinematics(self):
        """Position (s, alpha) and their theta-derivatives (kinematics at omega = 1)."""
        theta, phi = ca.SX.sym("theta"), ca.SX.sym("phi")
        s, alpha, res = self.solve_position(theta, phi)
        k = self.kinematics_at(theta, 1.0, 0.0, phi, s, alpha, res)
        return ca.Function("vane_kinematics", [theta, phi, self.p],
                           [s, alpha, k["sdot"], k["alphadot"], res],
                           ["theta", "phi", "p"], ["s", "alpha", "ds", "dalpha", "residual"],
                           {"cse": True})

    def gas_loads(self, theta, phi, s, alpha, p_lead, p_trail, p_slot):
        """Generalised forces of the gas on vane i (slide, lateral, tilt about G) and its moment on
        the rotor: p_lead on the +w side (cell i), p_trail on the -w side (cell i-1), p_slot under
        the vane (rotor-frame components, see cells.py); the slot-bottom gas pushes the rotor back."""
        W, h = self.P["rotor.width"], self.P["vane.thickness"]
        o = self.geo.outline(theta, phi, s, alpha)
        lead, trail, _, _, _ = self.geo.vane_pieces(o)
        loads = [(p_lead * W * f, X) for f, X in lead] + [(p_trail * W * f, X) for f, X in trail]
        loads.append((p_slot * h * W * o["u"], o["A"]))
        u, w, G = o["u"], o["w"], o["G"]
        gf_slide = sum(ca.dot(F, u) for F, _ in loads)
        gf_lat = sum(ca.dot(F, w) for F, _ in loads)
        gf_tilt = sum((X[0] - G[0]) * F[1] - (X[1] - G[1]) * F[0] for F, X in loads)
        gf_rotor = sum(X[0] * F[1] - X[1] * F[0] for F, X in loads)
        F_b, Ob = -p_slot * h * W * u, o["Ob"]  # slot-bottom gas on the rotor
        gf_rotor += Ob[0] * F_b[1] - Ob[1] * F_b[0]
        return gf_slide, gf_lat, gf_tilt, gf_rotor

    def vane_geometry(self, theta, phi, s, alpha):
        """What the vane dynamics needs of the angle alone (VANE_GEOMETRY, rotor frame): the
        housing point and normal at the tip contact, ds/dtheta and d2s/dtheta2 (sdot = ds omega,
        sddot = ds omegadot + d2s omega^2: the constraint's velocity terms are quadratic in omega),
        and the gas loads' coefficients of p_lead, p_trail, p_slot (the loads are linear in them)."""
        k = self.kinematics_at(theta, 1.0, 0.0, phi, s, alpha)
        hs = self.housing(alpha)
        C, n = self.to_rotor(theta, hs["C"]), self.to_rotor(theta, hs["n"])
        pr = ca.SX.sym("pressures", 3)
        loads = ca.vertcat(*self.gas_loads(theta, phi, s, alpha, pr[0], pr[1], pr[2]))
        coef = ca.substitute(ca.jacobian(loads, pr), pr, ca.DM.zeros(3))
        return ca.vertcat(C, n, k["sdot"], k["sddot"], ca.vec(coef))

    def vane_dynamics(self, given=False):
        """Model 2 vane at a solved position with gas loads: p_lead acts on the +w side (cell i),
        p_trail on the -w side (cell i-1), p_slot under the vane. given: the angle-only part
        (vane_geometry) is an input "vane" instead."""
        names = ("theta", "omega", "omegadot", "phi", "factor", "s", "alpha", "p_lead", "p_trail",
                 "p_slot")
        theta, omega, omegadot, phi, factor, s, alpha, p_lead, p_trail, p_slot = (
            ca.SX.sym(n) for n in names)
        P = self.P
        vg = ca.SX.sym("vane", len(VANE_GEOMETRY)) if given else self.vane_geometry(theta, phi, s, alpha)
        sdot, sddot = vg[4] * omega, vg[4] * omegadot + vg[5] * omega * omega
        g = self.geometry()
        common = dict(theta=theta, omega=omega, omegadot=omegadot, phi=phi, s=s,
                      sdot=sdot, sddot=sddot, Cx=vg[0], Cy=vg[1], nx=vg[2], ny=vg[3],
                      c_visc=P["effects.viscous_tip_friction"], **g)
        v_t = self.mech(**common)["tip_slip"]
        mu_h = factor * self.friction(v_t, "housing")
        mu_r = factor * self.friction(sdot, "slot")  # a vane's material/finish: tip and slot
        common.update(mu_h=mu_h, mu_r=mu_r)
        gf_slide, gf_lat, gf_tilt, gf_rotor = (
            ca.mtimes(ca.reshape(vg[6:18], 4, 3), ca.vertcat(p_lead, p_trail, p_slot))[i] for i in range(4))
        best, n_cons, amb, final = self.solve_contact_sides(("N", "F1", "F2"), common,
                                                          extra=(gf_slide, gf_lat, gf_tilt))
        share = final["torque_share"] - gf_rotor
        fric = (best[0] * mu_h * v_t + P["effects.viscous_tip_friction"] * v_t * v_t
                + mu_r * sdot * (ca.fabs(best[1]) + ca.fabs(best[2])))
        outs = dict(torque_share=share, torque_slope=ca.jacobian(share, omegadot), normal=best[0],
                    slot1=best[1], slot2=best[2], n_consistent=n_cons, friction_power=fric,
                    load_power=omega * gf_rotor + sdot * gf_slide, sdot=sdot,
                    kinetic_energy=final["kinetic_energy"], tip_slip=v_t, mu_housing=mu_h, mu_slot=mu_r,
                    ambiguity=amb)
        ins = [theta, omega, omegadot, phi, factor, s, alpha, p_lead, p_trail, p_slot]
        return ca.Function("vane_dynamics", ins + ([vg] if given else []) + [self.p],
                           [outs[nm] for nm in VANE_DYN_OUTPUTS],
                           [*names, *(["vane"] if given else []), "p"], list(VANE_DYN_OUTPUTS), {"cse": True})

    def cell_function(self, rates=False):
        """Cell volumes and d/dtheta, port overlaps, wall areas, from (theta, s, alpha, s', alpha')
        (rates: from (theta, s, alpha, sdot, alphadot, omega), d/dt instead of d/dtheta)."""
        N = self.st.vanes
        P = self.P
        theta = ca.SX.sym("theta")
        s, al, ds, dal = (ca.SX.sym(n, N) for n in ("s", "alpha", "ds", "dalpha"))
        c = self.geo.cells(theta, [s[i] for i in range(N)], [al[i] for i in range(N)])
        W = P["rotor.width"]
        V = ca.vertcat(*c["area"]) * W
        q = ca.vertcat(theta, s, al)
        omega = ca.SX.sym("omega")
        dV = ca.jtimes(V, q, ca.vertcat(omega if rates else 1.0, ds, dal))
        psi = P["housing.angle"]

        def port(name):
            lo, hi = P[f"ports.{name}.start"] + psi, P[f"ports.{name}.end"] + psi
            return ca.vertcat(*[self.geo.overlap_length(c["a0"][i], c["span"][i], lo, hi)
                                for i in range(N)])

        flanks = []
        for i in range(N):
            o_i, o_j = c["outlines"][i], c["outlines"][(i + 1) % N]
            flanks.append(exposed_flank(o_i, 1) + exposed_flank(o_j, -1))
        wall = (2 * ca.vertcat(*c["area"])
                + W * (ca.vertcat(*c["arc"]) + ca.vertcat(*c["rotor_arc"]) + ca.vertcat(*flanks)))
        # exposed length of vane i (mean of its flanks), for the end-face leak across it
        exposed = ca.vertcat(*[0.5 * (exposed_flank(o, 1) + exposed_flank(o, -1))
                               for o in c["outlines"]])
        vane_area = ca.vertcat(*c["vane_area"]) * W
        return ca.Function("cells", [theta, s, al, ds, dal, *([omega] if rates else []), self.p],
                           [V, dV, port("inlet"), port("exhaust"), wall, exposed, vane_area],
                           ["theta", "s", "alpha", "ds", "dalpha", *(["omega"] if rates else []), "p"],
                           ["volume", "dvolume", "inlet_length", "exhaust_length", "wall_area",
                            "exposed", "vane_volume"], {"cse": True})


def exposed_flank(o, side):
    """Length of a vane flank (side +1: +w, -1: -w) outside the rotor: from the rotor circle (R)
    to the flank's end at the tip (J), measured along the vane axis u. Near top dead centre the
    flank ends inside the rotor (only the tip cap protrudes): the signed length is negative there
    and the flank exposes nothing, so it is clamped at zero."""
    J, R = (o["Jp"], o["Rp"]) if side > 0 else (o["Jm"], o["Rm"])
    return ca.fmax(ca.dot(J - R, o["u"]), 0.0)


def build_pneumatic_model(structure) -> BuiltModel:
    b = GasBuilder(structure)
    N = structure.vanes
    p, P = parameter_symbols(b)
    phis = b.slot_angles(p)
    geometry = cell_geometry(b, p, phis)
    rates = pump_rates(b, p, P)
    x = ca.MX.sym("x", len(state_names(N)))
    geo = geometry(x[0])
    r = rates(x, geo)
    gs, fl, drive, od, W = r["gs"], r["fl"], r["drive"], r["od"], r["gs"]["W"]
    cur, omega, m = x[2], x[1], x[3:3 + N]
    m_in, m_ex, m_b, _, _ = plenum_state(x, N)
    rhs, jac, wd = implicit_rates(x, r["xdot"], r["qdot"], drive, p)
    fric_power, gas_power = r["friction_power"], r["gas_power"]
    outs = dict(
        torque=drive["torque"], omegadot=drive["omegadot_used"], current=cur, pressure=gs["pc"],
        volume=geo["V"], temperature=gs["Tc"], dvolume=geo["dV"], inlet_pressure=gs["p_in"],
        exhaust_pressure=gs["p_ex"], booster_pressure=gs["p_b"], slot_pressure=gs["p_slot"],
        gas_torque=-ca.dot(gs["pc"], geo["dV"]) - gs["p_slot"] * P("vane.thickness") * W * ca.sum2(geo["ds"]),
        friction_power=fric_power, gas_power=gas_power,
        load_power=ca.sum2(od["load_power"]), kinetic_energy=ca.sum2(od["kinetic_energy"]),
        normal=od["normal"].T, slot1=od["slot1"].T, slot2=od["slot2"].T,
        n_consistent=od["n_consistent"].T, s=geo["s"].T, position_residual=geo["residual"].T,
        inlet_flow=fl["f_in"], exhaust_flow=fl["f_ex"], leak_flow=fl["f_lk"], hose_flow=fl["f_hose"],
        booster_leak=fl["f_bleak"], valve_flow=fl["f_valve"], reed_force=fl["F_reed"],
        mass_total=ca.sum1(m) + m_in + m_ex + m_b, inlet_length=geo["lin"],
        exhaust_length=geo["lex"], vane_volume=geo["vane_volume"],
        motor_residual=ca.if_else(drive["motor"], drive["residual"], 0.0),
        sdot=od["sdot"].T, tip_slip=od["tip_slip"].T, mu_housing=od["mu_housing"].T,
        mu_slot=od["mu_slot"].T, ambiguity=od["ambiguity"].T,
    )
    out_s = ca.Function("outputs_at", [x, drive["omegadot_symbol"], p], list(outs.values()))
    out_fn = flat(ca.Function("pump_outputs", [x, p], out_s(x, wd, p), ["x", "p"], list(outs)))
    fns = {f.name(): f for f in (cell_geometry_function(geometry, p), orifice_function(P, p), rhs,
                                 jac, out_fn, *tabulated_kernels(b, geometry, x, p, P, phis))}
    return BuiltModel(structure, b.params, fns)


# -- pieces of the right-hand side, shared with the contact-model variant -------------------------
def parameter_symbols(b):
    """The runtime parameter vector p (MX) and P(name) -> its entry."""
    names = [q.name for q in b.params]
    p = ca.MX.sym("p", len(names))
    return p, lambda name: p[names.index(name)]


def pump_rates(b, p, P, given=False):
    """(x, geo) -> the rates of the state (xdot, as functions of the omegadot symbol) and of the
    quadratures, with the gas state, flows, motor drive and vane outputs they come from; geo: the
    cell geometry at x[0] (cell_geometry's, or the same quantities from a table; given: with the
    vanes' angle-only part, geo["vane"], from it too)."""
    N = b.st.vanes
    dyn_map = b.vane_dynamics(given).map(N)
    phis, facs = b.slot_angles(p), b.factors(p)
    Ir, tb = P("rotor.inertia"), P("operation.bearing_torque")

    def rates(x, geo):
        theta, omega, cur = x[0], x[1], x[2]
        m, U = x[3:3 + N], x[3 + N:3 + 2 * N]
        xr, vr = x[x.size1() - 2], x[x.size1() - 1]
        gs = gas_state(P, m, U, geo["V"], *plenum_state(x, N))
        fl = gas_flows(P, N, gs, geo["lin"], geo["lex"], geo["exposed"], xr, vr)
        # mechanics: required shaft torque at omegadot, gas loads included
        p_trail = ca.vertcat(*[gs["pc"][j] for j in fl["prev"]])

        def required(wd):
            o = dyn_map(theta, omega, wd, phis, facs, geo["s"], geo["alpha"], gs["pc"].T, p_trail.T,
                        gs["p_slot"], *([geo["vane"]] if given else []), p)
            od = dict(zip(VANE_DYN_OUTPUTS, o))
            return Ir * wd + tb + ca.sum2(od["torque_share"]), od

        drive = motor_drive(P, omega, cur, required, Ir, P("motor.inertia"))
        od = drive["outputs"]
        xdot = ca.vertcat(omega, drive["omegadot_used"], drive["current_rate"], fl["dm"],
                          energy_rows(P, N, gs, fl, geo["dV"], geo["wall"], omega), fl["dm_in"],
                          fl["dm_ex"], fl["dm_b"], plenum_energy_rows(N, gs, fl), fl["xr_dot"],
                          fl["vr_dot"])
        slot_rate = P("vane.thickness") * gs["W"] * ca.sum2(od["sdot"])
        gas_power = -ca.dot(gs["pc"], geo["dV"]) * omega - gs["p_slot"] * slot_rate
        fric_power = ca.sum2(od["friction_power"]) + tb * omega
        qdot = budget_rates(P, cur, omega, drive, fl, gas_power, fric_power)
        return dict(gs=gs, fl=fl, drive=drive, od=od, xdot=xdot, qdot=qdot, gas_power=gas_power,
                    friction_power=fric_power)

    return rates


# the geometry the right-hand side reads, in the order of a geometry table's columns; alpha as
# its offset from the vane's slot direction theta + phi wrapped to (-pi, pi] (periodic in theta
# like the others, and smooth: the offset stays far from pi); the right-hand side reads alpha
# only through 2 pi-periodic functions
TABLE_FIELDS = ("s", "alpha", "V", "dV", "lin", "lex", "wall", "exposed", "vane")


def geometry_vector(geo, theta, phis):
    """The table's columns (TABLE_FIELDS, N each) from cell_geometry's dict at theta."""
    def column(k):
        if k != "alpha":
            return ca.vec(geo[k])
        d = ca.vec(geo[k] - theta - phis)
        return d - TWO_PI * ca.floor(d / TWO_PI + 0.5)

    return ca.vertcat(*[column(k) for k in TABLE_FIELDS])


def geometry_from_vector(g, theta, phis, N):
    """cell_geometry's dict (the fields the rates read) from a table row g at theta; "vane":
    VANE_GEOMETRY x N."""
    geo = {k: g[i * N:(i + 1) * N] for i, k in enumerate(TABLE_FIELDS[:-1])}
    geo["s"], geo["alpha"] = geo["s"].T, geo["alpha"].T + theta + phis
    geo["vane"] = ca.reshape(g[(len(TABLE_FIELDS) - 1) * N:], len(VANE_GEOMETRY), N)
    return geo


def tabulated_kernels(b, geometry, x, p, P, phis):
    """The right-hand side with the angle-only geometry as an input (the cells', and the vanes'
    vane_geometry), for a table of it over one revolution (the direct CVODES driver's):
    geometry_table(theta, p) -> (g, dg/dtheta),
    pump_rhs_tab(x, g, p) -> (xdot, qdot) and pump_rhs_tab_jac(x, g, dg, p): the Jacobian in x
    with g's theta-dependence through dg (the chain rule: column theta gets J_g dg)."""
    N = b.st.vanes
    rates = pump_rates(b, p, P, given=True)
    th, s_, a_, ph_ = (ca.SX.sym(n) for n in ("theta", "s", "alpha", "phi"))
    vane = ca.Function("vane_geometry", [th, ph_, s_, a_, b.p], [b.vane_geometry(th, ph_, s_, a_)]).map(N)
    th = ca.MX.sym("theta")
    geo = geometry(th)
    geo["vane"] = vane(th, phis, geo["s"], geo["alpha"], p)
    g_th = geometry_vector(geo, th, phis)
    # dense: the table's rows are read as plain arrays (a structural zero would shift the columns)
    table = flat(ca.Function("geometry_table", [th, p], [ca.densify(g_th), ca.densify(ca.jacobian(g_th, th))],
                             ["theta", "p"], ["geometry", "dgeometry"]))
    g, dg, th_ref = ca.MX.sym("g", g_th.size1()), ca.MX.sym("dg", g_th.size1()), ca.MX.sym("theta_ref")
    r = rates(x, geometry_from_vector(g, x[0], phis, N))
    rhs, _, _ = implicit_rates(x, r["xdot"], r["qdot"], r["drive"], p, extra=[g], name="pump_rhs_tab")
    # g follows theta to first order about theta_ref; evaluated at theta_ref = x[0] it is g itself
    r = rates(x, geometry_from_vector(g + dg * (x[0] - th_ref), x[0], phis, N))
    _, jac, _ = implicit_rates(x, r["xdot"], r["qdot"], r["drive"], p, extra=[th_ref, g, dg],
                               name="pump_rhs_tab")
    jac = flat(ca.Function("pump_rhs_tab_jac", [x, g, dg, p], jac(x, x[0], g, dg, p), ["x", "g", "dg", "p"],
                           jac.name_out()))
    return table, rhs, jac


def cell_geometry(b, p, phis):
    """theta -> Model 2 vane positions (s, alpha and d/dtheta) and the cells at them: volumes V,
    dV/dtheta, port overlap lengths, wall areas, exposed vane lengths, vane volumes."""
    N = b.st.vanes
    kin_map = b.vane_kinematics().map(N)
    cell_fn = b.cell_function()

    def geometry(theta):
        s, al, ds, dal, res = kin_map(theta, phis, p)
        V, dV, lin, lex, wall, exposed, vvol = cell_fn(theta, s.T, al.T, ds.T, dal.T, p)
        return dict(s=s, alpha=al, ds=ds, dalpha=dal, residual=res, V=V, dV=dV, lin=lin, lex=lex,
                    wall=wall, exposed=exposed, vane_volume=vvol)

    return geometry


def gas_state(P, m, U, V, m_in, m_ex, m_b, U_in, U_ex) -> dict:
    """Gas constants, the cells' axial width W, cell pressures pc and temperatures Tc from
    (m, U, V); manifold and exhaust-port pressures and temperatures (p_in, T_in, p_ex, T_ex) from
    their (m, U); the booster pressure (isothermal at gas.temperature); the slot-bottom pressure."""
    R, g = P("gas.gas_constant"), P("gas.gamma")
    cv, cp = R / (g - 1), g * R / (g - 1)
    T0, p_atm = P("gas.temperature"), P("gas.atmosphere")
    p_in = (g - 1) * U_in / P("ports.inlet_volume")
    p_ex = (g - 1) * U_ex / P("ports.exhaust_volume")
    src = P("vane.slot_pressure.source")
    p_slot = ca.if_else(src < 0.5, P("vane.slot_pressure.value"),
                        ca.if_else(src < 1.5, p_in, ca.if_else(src < 2.5, p_ex, p_atm)))
    return dict(R=R, g=g, cv=cv, cp=cp, T0=T0, p_atm=p_atm, W=P("rotor.width"), pc=(g - 1) * U / V,
                Tc=U / (m * cv), p_in=p_in, p_ex=p_ex, T_in=U_in / (m_in * cv), T_ex=U_ex / (m_ex * cv),
                p_b=m_b * R * T0 / P("booster.volume"), p_slot=p_slot)


def _flow(gs, p1, T1, p2, T2, area):
    return gas.orifice_flow(p1, T1, p2, T2, area, gs["R"], gs["g"])


def cell_flows(P, N, gs, lin, lex, exposed, lift_gap=None) -> dict:
    """Port flows (into cell i from the inlet manifold, out of it into the exhaust port) and the
    leak across vane j from cell j-1 to cell j (tip gap, plus a lifted vane's gap, and both end
    faces); prev/nxt: the neighbouring cells."""
    pc, Tc, W = gs["pc"], gs["Tc"], gs["W"]
    Cd = P("ports.discharge_coefficient")
    A_in = Cd * lin * P("ports.inlet.width")
    A_ex = Cd * lex * P("ports.exhaust.width")
    f_in = ca.vertcat(*[_flow(gs, gs["p_in"], gs["T_in"], pc[i], Tc[i], A_in[i]) for i in range(N)])
    f_ex = ca.vertcat(*[_flow(gs, pc[i], Tc[i], gs["p_ex"], gs["T_ex"], A_ex[i]) for i in range(N)])
    tip = P("leak.tip_gap") if lift_gap is None else P("leak.tip_gap") + lift_gap
    A_leak = P("leak.discharge_coefficient") * (tip * W + 2 * P("leak.end_gap") * exposed)
    prev = [(j - 1) % N for j in range(N)]
    f_lk = ca.vertcat(*[_flow(gs, pc[prev[j]], Tc[prev[j]], pc[j], Tc[j], A_leak[j])
                        for j in range(N)])
    if N == 1:
        f_lk = 0 * f_lk  # one cell: the leak across the only vane returns to the same cell
    return dict(f_in=f_in, f_ex=f_ex, f_lk=f_lk, prev=prev, nxt=[(i + 1) % N for i in range(N)])


def booster_flows(P, gs) -> dict:
    """Booster -> hose and inlet check valve -> manifold; atmosphere -> booster leak."""
    T0, p_atm, p_b, p_in = gs["T0"], gs["p_atm"], gs["p_b"], gs["p_in"]
    # hose orifice and check valve in series, the valve's area growing to the hose's at full
    # lift: the smaller effective area of the two passes the flow
    lift = gas.ramp(p_b - p_in, P("ports.check_cracking"), P("ports.check_full_open"))
    A_hose = P("ports.hose_area") * ca.fmin(P("ports.hose_discharge_coefficient"),
                                            P("ports.check_discharge_coefficient") * lift)
    A_bleak = P("booster.leak") / gas.choked_flux(p_atm, T0, gs["R"], gs["g"])
    return dict(f_hose=_flow(gs, p_b, T0, p_in, gs["T_in"], A_hose),
                f_bleak=_flow(gs, p_atm, T0, p_b, T0, A_bleak))


def exhaust_valve(P, gs, xr, vr) -> dict:
    """Exhaust port -> atmosphere through the check valve or the reed (lift xr, rate vr: its rates
    while free, its damping power)."""
    T0, p_atm, p_ex = gs["T0"], gs["p_atm"], gs["p_ex"]
    reed = P("valve.reed") > 0.5
    A_check = P("valve.area") * gas.ramp(p_ex - p_atm, P("valve.cracking"), P("valve.full_open"))
    A_reed = ca.fmin(math.pi * P("valve.diameter") * ca.fmax(xr, 0.0), P("valve.area"))
    f_valve = _flow(gs, p_ex, gs["T_ex"], p_atm, T0,
                    P("valve.discharge_coefficient") * ca.if_else(reed, A_reed, A_check))
    F_reed = (p_ex - p_atm) * P("valve.force_area") - P("valve.preload") - P("valve.stiffness") * xr
    free = ca.logic_and(reed, P("valve.mode") < 0.5)
    return dict(f_valve=f_valve, F_reed=F_reed, free=free, xr_dot=ca.if_else(free, vr, 0.0),
                vr_dot=ca.if_else(free, (F_reed - P("valve.damping") * vr) / P("valve.mass"), 0.0),
                valve_damping=ca.if_else(free, P("valve.damping") * vr * vr, 0.0))


def gas_flows(P, N, gs, lin, lex, exposed, xr, vr, lift_gap=None) -> dict:
    """Every flow of the gas network and the mass rows: dm (cells), dm_in (manifold), dm_ex
    (exhaust port), dm_b (booster); the reed's rates."""
    fl = cell_flows(P, N, gs, lin, lex, exposed, lift_gap)
    fl.update(booster_flows(P, gs))
    fl.update(exhaust_valve(P, gs, xr, vr))
    f_in, f_ex, f_lk, nxt = fl["f_in"], fl["f_ex"], fl["f_lk"], fl["nxt"]
    fl.update(dm=ca.vertcat(*[f_in[i] - f_ex[i] + f_lk[i] - f_lk[nxt[i]] for i in range(N)]),
              dm_in=fl["f_hose"] - ca.sum1(f_in), dm_ex=ca.sum1(f_ex) - fl["f_valve"],
              dm_b=fl["f_bleak"] - fl["f_hose"])
    return fl


def energy_rows(P, N, gs, fl, dV, wall, omega=None):
    """dU_i/dt: enthalpy carried by every flow (upstream temperature), the p dV work and the wall
    heat. dV is dV/dtheta with omega given (Model 2), else dV/dt."""
    T_in, T_ex, Tc, pc, cp = gs["T_in"], gs["T_ex"], gs["Tc"], gs["pc"], gs["cp"]
    prev, nxt = fl["prev"], fl["nxt"]
    f_in, f_ex, f_lk = fl["f_in"], fl["f_ex"], fl["f_lk"]
    Q = P("gas.heat_transfer") * wall * (P("gas.wall_temperature") - Tc)
    work = [pc[i] * omega * dV[i] if omega is not None else pc[i] * dV[i] for i in range(N)]
    return ca.vertcat(*[
        gas.enthalpy_flow(f_in[i], T_in, Tc[i], cp) - gas.enthalpy_flow(f_ex[i], Tc[i], T_ex, cp)
        + gas.enthalpy_flow(f_lk[i], Tc[prev[i]], Tc[i], cp)
        - gas.enthalpy_flow(f_lk[nxt[i]], Tc[i], Tc[nxt[i]], cp)
        - work[i] + Q[i] for i in range(N)])


def plenum_energy_rows(N, gs, fl):
    """dU_in/dt, dU_ex/dt of the manifold and the exhaust port (rigid, adiabatic): the enthalpy the
    flows carry in and out, each at its upstream temperature (the booster's gas.temperature, the
    atmosphere's on a back-flow through the valve)."""
    T0, T_in, T_ex, Tc, cp = gs["T0"], gs["T_in"], gs["T_ex"], gs["Tc"], gs["cp"]
    f_in, f_ex = fl["f_in"], fl["f_ex"]
    dU_in = (gas.enthalpy_flow(fl["f_hose"], T0, T_in, cp)
             - sum(gas.enthalpy_flow(f_in[i], T_in, Tc[i], cp) for i in range(N)))
    dU_ex = (sum(gas.enthalpy_flow(f_ex[i], Tc[i], T_ex, cp) for i in range(N))
             - gas.enthalpy_flow(fl["f_valve"], T_ex, T0, cp))
    return ca.vertcat(dU_in, dU_ex)


def motor_drive(P, omega, cur, required, rotor_inertia, motor_inertia) -> dict:
    """Shaft balance. Constant speed (operation.motor = 0: omegadot = 0, the torque is the inverse
    dynamics) or the brushed DC motor: omegadot from k i - tau_f - I_m omegadot = required(omegadot)
    (required(wd) -> (torque, per-vane outputs with torque_slope)) by Newton steps on the
    piecewise-affine required torque; di/dt = (V - R i - k omega) / L."""
    motor = P("operation.motor") > 0.5
    k_m = P("motor.constant")
    tau_mf = P("motor.friction") * ca.tanh(omega / MOTOR_FRICTION_SPEED)
    tau_motor = k_m * cur - tau_mf

    def residual(wd):
        rt, od = required(wd)
        return rt + motor_inertia * wd - tau_motor, od

    # the rates as functions of (x, omegadot): the gas rows never see the mechanics
    wd_s = ca.MX.sym("omegadot")
    wd_use = ca.if_else(motor, wd_s, 0.0)
    tau, od = required(wd_use)
    di = ca.if_else(motor, (P("motor.voltage") - P("motor.resistance") * cur - k_m * omega)
                    / P("motor.inductance"), 0.0)
    wd = ca.MX(0.0)
    for _ in range(MOTOR_NEWTON_ITERATIONS):
        r, o = residual(wd)
        wd = wd - r / (rotor_inertia + motor_inertia + ca.sum2(o["torque_slope"]))
    r_s, o_s = residual(wd_s)
    return dict(motor=motor, omegadot_symbol=wd_s, omegadot_used=wd_use, omegadot=wd, torque=tau,
                outputs=od, residual=r_s,
                slope=rotor_inertia + motor_inertia + ca.sum2(o_s["torque_slope"]),
                motor_friction=tau_mf, voltage=ca.if_else(motor, P("motor.voltage"), 0.0),
                current_rate=di)


def budget_rates(P, cur, omega, drive, fl, gas_power, fric_power, *extra):
    """Quadrature rates in QUAD_NAMES order (then `extra`): electrical energy, shaft, gas and
    friction work, copper loss, motor friction, valve damping, net mass from the atmosphere."""
    return ca.vertcat(drive["voltage"] * cur, drive["torque"] * omega, gas_power, fric_power,
                      P("motor.resistance") * cur * cur, drive["motor_friction"] * omega,
                      fl["valve_damping"], fl["f_bleak"] - fl["f_valve"], *extra)


def implicit_rates(x, xdot, qdot, drive, p, extra=(), name="pump_rhs"):
    """`name` and `name`_jac from the rates as functions of (x, omegadot symbol), their inputs
    (x, *extra, p). omegadot: Newton on the piecewise-affine residual (each vane returns its
    slope); its derivative by the implicit function theorem, d wd/dx = -(dr/dx) / (dr/dwd), from
    one reverse sweep, so the Jacobian never differentiates through the iterations. Returns
    (rhs, jac, omegadot)."""
    wd_s, wd, r_s = drive["omegadot_symbol"], drive["omegadot"], drive["residual"]
    J = (ca.jacobian(xdot, x)
         - ca.mtimes(ca.jacobian(xdot, wd_s), ca.gradient(r_s, x).T) / drive["slope"])
    ins, names = [x, *extra, p], ["x", *[e.name() for e in extra], "p"]
    rates = ca.Function("rates", [x, wd_s, *extra, p], [xdot, qdot])
    xdot_v, qdot_v = rates(x, wd, *extra, p)
    J_v = ca.Function("rates_jac", [x, wd_s, *extra, p], [J])(x, wd, *extra, p)
    rhs = ca.Function(name, ins, [xdot_v, qdot_v], names, ["xdot", "qdot"])
    # the quadratures do not feed back: their Jacobian rows are left to CVODES' Newton iteration
    # (which then converges on them in one extra step at most) -- zero rows here
    jac = ca.Function(name + "_jac", ins, [J_v, ca.MX(qdot.size1(), x.size1())],
                      names, ["jac_xdot_x", "jac_qdot_x"])
    return flat(rhs), flat(jac), wd


def flat(f):
    """f as one scalar (SX) graph with common subexpressions merged. The MX form calls the cell
    geometry once per Newton step and again in the rates, and differentiates through function
    calls; flat, the same operations in the same order (equal to rounding) run without the
    repeats: on the EVP example pump_rhs 18 -> 6 us and pump_rhs_jac 51 -> 13 us per call."""
    return f.expand(f.name(), {"cse": True})


def cell_geometry_function(geometry, p):
    """cell_geometry(theta, p): the Model 2 cells (the runtime's start state and plots; the
    exposed vane lengths and wall areas for the geometry tests)."""
    th = ca.MX.sym("theta")
    gg = geometry(th)
    return ca.Function("cell_geometry", [th, p],
                       [gg["V"], gg["dV"], gg["vane_volume"], gg["lin"], gg["lex"], gg["s"].T,
                        gg["alpha"].T, gg["residual"].T, gg["exposed"], gg["wall"]],
                       ["theta", "p"], ["volume", "dvolume", "vane_volume", "inlet_length",
                                        "exhaust_length", "s", "alpha", "position_residual",
                                        "exposed", "wall_area"])


def orifice_function(P, p):
    """orifice_flow(p1, T1, p2, T2, area, p): the compiled orifice law (closed-form tests)."""
    a = [ca.MX.sym(n) for n in ("p1", "T1", "p2", "T2", "area")]
    R, g = P("gas.gas_constant"), P("gas.gamma")
    return ca.Function("orifice_flow", [*a, p], [gas.orifice_flow(*a, R, g)],
                       ["p1", "T1", "p2", "T2", "area", "p"], ["mdot"])
