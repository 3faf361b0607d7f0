"""Model 1 with gas (spec §2 and §8): every vane free in its slot (s_i, sdot_i integrated), tip
and slot-bottom penalty contacts, integrated together with the gas cells, ports, valves, leaks,
booster and motor of the pneumatic model.

The gas acts on each vane as in Model 2 (`_GasBuilder.gas_loads`): p_i on the +w side (cell i),
p_{i-1} on the -w side, p_slot under the vane; these loads enter the three vane equations, which
are solved for (sddot, F1, F2) given the penalty forces (`contact_model.contact_vane`), and their
moment enters the drive torque. A vane the gas pushes off the housing lifts (penetration < 0,
normal force 0); the lift gap -penetration opens a tip leak between its two cells in addition to
leak.tip_gap. The cells are the Model 2 cells at the vanes' actual (s_i, alpha_i): alpha_i is the
housing point of the contact model (the foot of the housing normal through the tip-arc centre),
so with a lifted vane the cell boundary crosses the gap along that normal; dV_i/dt follows
exactly from (omega, sdot_i, alphadot_i).

State x (state_names): theta, omega, current, cell masses m_i, cell energies U_i, inlet manifold,
exhaust port and booster masses, s_i, sdot_i, reed lift and lift rate (the reed stays last, the
booster index is the pneumatic model's). Quadratures: the pneumatic model's QUAD_NAMES, then
contact_work (elastic storage + damping of the penalty contacts) and load_work (work of the gas
forces on vanes and rotor). Energy: shaft work = friction + contact + kinetic energy change -
load work exactly; gas work (-oint sum p dV - p_slot dV_slot) equals -load work up to the work
of the cell boundaries' non-material pieces (the tip-to-housing segment along the normal, of
length |penetration|), which is reported (load_power vs gas_power) and small.
"""
from __future__ import annotations

import math

import casadi as ca

from pumpsim.model_spec.outputs import PUMP_CONTACT_OUTPUTS, VANE_OUTPUTS

from . import gas
from .contact_model import contact_vane, housing_contact
from .model import BuiltModel
from .pneumatic_model import MOTOR_FRICTION_SPEED, MOTOR_NEWTON_ITERATIONS, _GasBuilder

QUAD_NAMES = ("electrical_energy", "shaft_work", "gas_work", "friction_work", "copper_loss",
              "motor_friction_work", "valve_damping_work", "atmosphere_mass", "contact_work",
              "load_work")
VANE_GAS_OUTPUTS = ("sddot", "torque_share", "torque_slope", "normal", "slot1", "slot2", "bottom",
                    "penetration", "alpha", "tip_slip", "kinetic_energy", "potential_energy",
                    "friction_power", "contact_power", "load_power", "n_consistent", "ambiguity",
                    "position_residual")


def state_names(N):
    return (["theta", "omega", "current"] + [f"mass_{i}" for i in range(N)]
            + [f"energy_{i}" for i in range(N)] + ["inlet_mass", "exhaust_mass", "booster_mass"]
            + [f"s_{i}" for i in range(N)] + [f"sdot_{i}" for i in range(N)]
            + ["reed_lift", "reed_rate"])


def vane_gas_function(b) -> ca.Function:
    """One free vane with gas loads: p_lead on its +w side (cell i), p_trail on its -w side."""
    names = ("theta", "omega", "omegadot", "s", "sdot", "phi", "factor", "p_lead", "p_trail", "p_slot")
    th, w, wd, s, sd, phi, factor, p_lead, p_trail, p_slot = (ca.SX.sym(n) for n in names)
    held = {}

    def loads(alpha):
        held["gf"] = b.gas_loads(th, phi, s, alpha, p_lead, p_trail, p_slot)
        return held["gf"]

    o = contact_vane(b, th, w, wd, s, sd, phi, factor, loads)
    gf_slide, _, _, gf_rotor = held["gf"]
    o["load_power"] = w * gf_rotor + sd * gf_slide
    return ca.Function("vane_gas_contact", [th, w, wd, s, sd, phi, factor, p_lead, p_trail, p_slot, b.p],
                       [o[k] for k in VANE_GAS_OUTPUTS], [*names, "p"], list(VANE_GAS_OUTPUTS),
                       {"cse": True})


def contact_point_function(b) -> ca.Function:
    """alpha, alphadot and the penetration of one vane at (theta, omega, s, sdot): the cells need
    them without the vane's dynamics."""
    th, w, s, sd, phi = (ca.SX.sym(n) for n in ("theta", "omega", "s", "sdot", "phi"))
    c = housing_contact(b, th, w, s, sd, phi)
    return ca.Function("contact_point", [th, w, s, sd, phi, b.p],
                       [c["alpha"], c["alphadot"], c["delta"]],
                       ["theta", "omega", "s", "sdot", "phi", "p"], ["alpha", "alphadot", "delta"],
                       {"cse": True})


def build_pneumatic_contact_model(structure) -> BuiltModel:
    b = _GasBuilder(structure)
    N = structure.vanes
    vane_map = vane_gas_function(b).map(N)
    point_map = contact_point_function(b).map(N)
    cell_rates = b.cell_function(rates=True)
    names = [q.name for q in b.params]
    p = ca.MX.sym("p", len(names))

    def P(name):
        return p[names.index(name)]

    phis, facs = b.slot_angles(p), b.factors(p)
    nx = len(state_names(N))
    x = ca.MX.sym("x", nx)
    theta, omega, cur = x[0], x[1], x[2]
    m, U = x[3:3 + N], x[3 + N:3 + 2 * N]
    m_in, m_ex, m_b = (x[3 + 2 * N + k] for k in range(3))
    s, sd = x[6 + 2 * N:6 + 3 * N], x[6 + 3 * N:6 + 4 * N]
    xr, vr = x[nx - 2], x[nx - 1]
    alpha, alphadot, delta = point_map(theta, omega, s.T, sd.T, phis, p)
    V, dVdt, lin, lex, wall, exposed, vvol = cell_rates(theta, s, alpha.T, sd, alphadot.T, omega, p)
    g_ = _gas_state(P, m, U, V, m_in, m_ex, m_b)
    lift_gap = ca.fmax(-delta.T, 0.0)  # a lifted vane's tip gap joins its two cells
    fl = _flows(P, N, g_, lin, lex, exposed, lift_gap, xr, vr)
    # mechanics: the drive torque each vane needs at omegadot, gas loads included
    prev = [(j - 1) % N for j in range(N)]
    p_trail = ca.vertcat(*[g_["pc"][prev[i]] for i in range(N)])
    Ir, tb = P("rotor.inertia"), P("operation.bearing_torque")

    def required(wd):
        o = vane_map(theta, omega, wd, s.T, sd.T, phis, facs, g_["pc"].T, p_trail.T, g_["p_slot"], p)
        od = dict(zip(VANE_GAS_OUTPUTS, o))
        return Ir * wd + tb + ca.sum2(od["torque_share"]), od

    drive = _motor_drive(P, omega, cur, required)
    wd_s, od = drive["omegadot_symbol"], drive["outputs"]
    xdot = ca.vertcat(omega, drive["omegadot_used"], drive["current_rate"], fl["dm"],
                      _energy_rows(P, N, g_, fl, dVdt, wall), fl["dm_in"], fl["dm_ex"], fl["dm_b"], sd,
                      od["sddot"].T, fl["xr_dot"], fl["vr_dot"])
    W, h = P("rotor.width"), P("vane.thickness")
    gas_power = -ca.dot(g_["pc"], dVdt) - g_["p_slot"] * h * W * ca.sum1(sd)
    fric_power = ca.sum2(od["friction_power"]) + tb * omega
    tau = drive["torque"]
    qdot = ca.vertcat(drive["voltage"] * cur, tau * omega, gas_power, fric_power,
                      P("motor.resistance") * cur * cur, drive["motor_friction"] * omega,
                      fl["valve_damping"], fl["f_bleak"] - fl["f_valve"],
                      ca.sum2(od["contact_power"]), ca.sum2(od["load_power"]))
    wd = drive["omegadot"]
    r_s, slope = drive["residual"], drive["slope"]
    J = ca.jacobian(xdot, x) - ca.mtimes(ca.jacobian(xdot, wd_s), ca.gradient(r_s, x).T) / slope
    rates = ca.Function("rates", [x, wd_s, p], [xdot, qdot])
    xdot_v, qdot_v = rates(x, wd, p)
    J_v = ca.Function("rates_jac", [x, wd_s, p], [J])(x, wd, p)
    rhs = ca.Function("pump_rhs", [x, p], [xdot_v, qdot_v], ["x", "p"], ["xdot", "qdot"])
    jac = ca.Function("pump_rhs_jac", [x, p], [J_v, ca.MX(qdot.size1(), nx)],
                      ["x", "p"], ["jac_xdot_x", "jac_qdot_x"])
    safe_omega = ca.if_else(ca.fabs(omega) > 1e-9, omega, 1.0)  # per-radian outputs at rest: 0
    at_rest = ca.fabs(omega) <= 1e-9
    outs = dict(
        torque=tau, omegadot=drive["omegadot_used"], current=cur, pressure=g_["pc"], volume=V,
        temperature=g_["Tc"], dvolume=ca.if_else(at_rest, 0 * dVdt, dVdt / safe_omega),
        inlet_pressure=g_["p_in"], exhaust_pressure=g_["p_ex"], booster_pressure=g_["p_b"],
        slot_pressure=g_["p_slot"], gas_torque=ca.if_else(at_rest, 0.0, gas_power / safe_omega),
        friction_power=fric_power, gas_power=gas_power, load_power=ca.sum2(od["load_power"]),
        kinetic_energy=ca.sum2(od["kinetic_energy"]), normal=od["normal"].T, slot1=od["slot1"].T,
        slot2=od["slot2"].T, n_consistent=od["n_consistent"].T, s=s,
        position_residual=od["position_residual"].T, inlet_flow=fl["f_in"], exhaust_flow=fl["f_ex"],
        leak_flow=fl["f_lk"], hose_flow=fl["f_hose"], booster_leak=fl["f_bleak"],
        valve_flow=fl["f_valve"], reed_force=fl["F_reed"],
        mass_total=ca.sum1(m) + m_in + m_ex + m_b, inlet_length=lin, exhaust_length=lex,
        vane_volume=vvol, motor_residual=ca.if_else(drive["motor"], r_s, 0.0),
        sdot=sd, penetration=od["penetration"].T, bottom=od["bottom"].T, alpha=od["alpha"].T,
        tip_slip=od["tip_slip"].T, ambiguity=od["ambiguity"].T,
        potential_energy=od["potential_energy"].T, contact_power=ca.sum2(od["contact_power"]),
        volume_rate=dVdt,
    )
    out_s = ca.Function("outputs_at", [x, wd_s, p], [outs[k] for k in PUMP_CONTACT_OUTPUTS])
    out_fn = ca.Function("pump_outputs", [x, p], out_s(x, wd, p), ["x", "p"], list(PUMP_CONTACT_OUTPUTS))
    fns = {f.name(): f for f in (rhs, jac, out_fn, *_start_functions(b, N))}
    return BuiltModel(structure, b.params, fns)


def _gas_state(P, m, U, V, m_in, m_ex, m_b) -> dict:
    """Cell pressures and temperatures, manifold, exhaust-port, booster and slot pressures."""
    R, g = P("gas.gas_constant"), P("gas.gamma")
    T0, p_atm = P("gas.temperature"), P("gas.atmosphere")
    p_in = m_in * R * T0 / P("ports.inlet_volume")
    p_ex = m_ex * R * T0 / P("ports.exhaust_volume")
    src = P("vane.slot_pressure.source")
    p_slot = ca.if_else(src < 0.5, P("vane.slot_pressure.value"),
                        ca.if_else(src < 1.5, p_in, ca.if_else(src < 2.5, p_ex, p_atm)))
    return dict(R=R, g=g, cv=R / (g - 1), cp=g * R / (g - 1), T0=T0, p_atm=p_atm,
                pc=(g - 1) * U / V, Tc=U / (m * R / (g - 1)), p_in=p_in, p_ex=p_ex,
                p_b=m_b * R * T0 / P("booster.volume"), p_slot=p_slot)


def _flows(P, N, s, lin, lex, exposed, lift_gap, xr, vr) -> dict:
    """Every mass flow of the gas network (ports, leaks with the lift gaps, hose and check valve,
    booster leak, exhaust valve) and the reed's rates."""
    R, g, T0, p_atm, pc, Tc = s["R"], s["g"], s["T0"], s["p_atm"], s["pc"], s["Tc"]
    p_in, p_ex, p_b = s["p_in"], s["p_ex"], s["p_b"]
    W = P("rotor.width")

    def flow(p1, T1, p2, T2, area):
        return gas.orifice_flow(p1, T1, p2, T2, area, R, g)

    Cd = P("ports.discharge_coefficient")
    A_in = Cd * lin * P("ports.inlet.width")
    A_ex = Cd * lex * P("ports.exhaust.width")
    f_in = ca.vertcat(*[flow(p_in, T0, pc[i], Tc[i], A_in[i]) for i in range(N)])
    f_ex = ca.vertcat(*[flow(pc[i], Tc[i], p_ex, T0, A_ex[i]) for i in range(N)])
    A_leak = P("leak.discharge_coefficient") * ((P("leak.tip_gap") + lift_gap) * W
                                                + 2 * P("leak.end_gap") * exposed)
    prev = [(j - 1) % N for j in range(N)]
    f_lk = ca.vertcat(*[flow(pc[prev[j]], Tc[prev[j]], pc[j], Tc[j], A_leak[j]) for j in range(N)])
    if N == 1:
        f_lk = 0 * f_lk  # one cell: the leak across the only vane returns to the same cell
    A_hose = P("ports.hose_area") * gas.ramp(p_b - p_in, P("ports.check_cracking"),
                                             P("ports.check_full_open"))
    f_hose = flow(p_b, T0, p_in, T0, A_hose)
    A_bleak = P("booster.leak") / gas.choked_flux(p_atm, T0, R, g)
    f_bleak = flow(p_atm, T0, p_b, T0, A_bleak)
    reed = P("valve.reed") > 0.5
    A_check = P("valve.area") * gas.ramp(p_ex - p_atm, P("valve.cracking"), P("valve.full_open"))
    A_reed = ca.fmin(math.pi * P("valve.diameter") * ca.fmax(xr, 0.0), P("valve.area"))
    f_valve = flow(p_ex, T0, p_atm, T0, ca.if_else(reed, A_reed, A_check))
    F_reed = (p_ex - p_atm) * P("valve.force_area") - P("valve.preload") - P("valve.stiffness") * xr
    free = ca.logic_and(reed, P("valve.mode") < 0.5)
    nxt = [(i + 1) % N for i in range(N)]
    return dict(
        f_in=f_in, f_ex=f_ex, f_lk=f_lk, f_hose=f_hose, f_bleak=f_bleak, f_valve=f_valve,
        F_reed=F_reed, prev=prev, nxt=nxt,
        dm=ca.vertcat(*[f_in[i] - f_ex[i] + f_lk[i] - f_lk[nxt[i]] for i in range(N)]),
        dm_in=f_hose - ca.sum1(f_in), dm_ex=ca.sum1(f_ex) - f_valve, dm_b=f_bleak - f_hose,
        xr_dot=ca.if_else(free, vr, 0.0),
        vr_dot=ca.if_else(free, (F_reed - P("valve.damping") * vr) / P("valve.mass"), 0.0),
        valve_damping=ca.if_else(free, P("valve.damping") * vr * vr, 0.0))


def _energy_rows(P, N, s, fl, dVdt, wall):
    """dU_i/dt: enthalpy carried by every flow (upstream temperature), p dV work, wall heat."""
    T0, Tc, pc, cp = s["T0"], s["Tc"], s["pc"], s["cp"]
    prev, nxt = fl["prev"], fl["nxt"]
    f_in, f_ex, f_lk = fl["f_in"], fl["f_ex"], fl["f_lk"]
    Q = P("gas.heat_transfer") * wall * (P("gas.wall_temperature") - Tc)
    return ca.vertcat(*[
        gas.enthalpy_flow(f_in[i], T0, Tc[i], cp) - gas.enthalpy_flow(f_ex[i], Tc[i], T0, cp)
        + gas.enthalpy_flow(f_lk[i], Tc[prev[i]], Tc[i], cp)
        - gas.enthalpy_flow(f_lk[nxt[i]], Tc[i], Tc[nxt[i]], cp)
        - pc[i] * dVdt[i] + Q[i] for i in range(N)])


def _motor_drive(P, omega, cur, required) -> dict:
    """Constant speed (operation.motor = 0: omegadot = 0, the torque is the inverse dynamics) or
    the brushed DC motor: omegadot from k i - tau_f - I_m omegadot = required(omegadot) by Newton
    steps on the piecewise-affine required torque (as the pneumatic model)."""
    motor = P("operation.motor") > 0.5
    k_m, Im, Ir = P("motor.constant"), P("motor.inertia"), P("rotor.inertia")
    tau_mf = P("motor.friction") * ca.tanh(omega / MOTOR_FRICTION_SPEED)
    tau_motor = k_m * cur - tau_mf

    def residual(wd):
        rt, od = required(wd)
        return rt + Im * wd - tau_motor, od

    wd_s = ca.MX.sym("omegadot")
    wd_use = ca.if_else(motor, wd_s, 0.0)
    tau, od = required(wd_use)
    wd = ca.MX(0.0)
    for _ in range(MOTOR_NEWTON_ITERATIONS):
        r, o = residual(wd)
        wd = wd - r / (Ir + Im + ca.sum2(o["torque_slope"]))
    r_s, o_s = residual(wd_s)
    return dict(motor=motor, omegadot_symbol=wd_s, omegadot_used=wd_use, omegadot=wd, torque=tau,
                outputs=od, residual=r_s, slope=Ir + Im + ca.sum2(o_s["torque_slope"]),
                motor_friction=tau_mf, voltage=ca.if_else(motor, P("motor.voltage"), 0.0),
                current_rate=ca.if_else(motor, (P("motor.voltage") - P("motor.resistance") * cur
                                                - k_m * omega) / P("motor.inductance"), 0.0))


def _start_functions(b, N):
    """Model 2's vane positions and cells (the runtime starts the vanes on the housing there):
    cell_geometry(theta) and constrained_state(theta, omega)."""
    kin_map = b.vane_kinematics().map(N)
    cell_fn = b.cell_function()
    p = ca.MX.sym("p", len(b.params))
    th, w = ca.MX.sym("theta"), ca.MX.sym("omega")
    phis, facs = b.slot_angles(p), b.factors(p)
    s, al, ds, dal, res = kin_map(th, phis, p)
    V, dV, lin, lex, _, _, vvol = cell_fn(th, s.T, al.T, ds.T, dal.T, p)
    cells = ca.Function("cell_geometry", [th, p], [V, dV, vvol, lin, lex, s.T, al.T, res.T],
                        ["theta", "p"], ["volume", "dvolume", "vane_volume", "inlet_length",
                                         "exhaust_length", "s", "alpha", "position_residual"])
    oc = b.vane_constrained().map(N)(th, w, 0.0, phis, facs, p)
    cstate = ca.Function("constrained_state", [th, w, p],
                         [oc[VANE_OUTPUTS.index(k)].T for k in ("s", "sdot", "normal")],
                         ["theta", "omega", "p"], ["s", "sdot", "normal"])
    return cells, cstate
