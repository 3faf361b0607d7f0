"""Model 1 with gas (spec §2 and §8): every vane free in its slot (s_i, sdot_i integrated), tip
and slot-bottom penalty contacts, integrated together with the gas cells, ports, valves, leaks,
booster and motor of the pneumatic model.

The gas acts on each vane as in Model 2 (`GasBuilder.gas_loads`): p_i on the +w side (cell i),
p_{i-1} on the -w side, p_slot under the vane; these loads enter the three vane equations, which
are solved for (sddot, F1, F2) given the penalty forces (`contact_model.contact_vane`), and their
moment enters the drive torque. A vane the gas pushes off the housing lifts (penetration < 0,
normal force 0); the lift gap -penetration opens a tip leak between its two cells in addition to
leak.tip_gap. The cells are the Model 2 cells at the vanes' actual (s_i, alpha_i): alpha_i is the
housing point of the contact model (the foot of the housing normal through the tip-arc centre),
so with a lifted vane the cell boundary crosses the gap along that normal; dV_i/dt follows
exactly from (omega, sdot_i, alphadot_i).

State x (state_names): theta, omega, current, cell masses m_i, cell energies U_i, inlet manifold,
exhaust port and booster masses, s_i, sdot_i, inlet-manifold and exhaust-port energies, reed
lift and lift rate (the reed stays last, the plenum energies just before it and the booster index
is the pneumatic model's). Quadratures: the pneumatic model's QUAD_NAMES, then
contact_work (elastic storage + damping of the penalty contacts) and load_work (work of the gas
forces on vanes and rotor). Energy: shaft work = friction + contact + kinetic energy change -
load work exactly; gas work (-oint sum p dV - p_slot dV_slot) equals -load work up to the work
of the cell boundaries' non-material pieces (the tip-to-housing segment along the normal, of
length |penetration|), which is reported (load_power vs gas_power) and small.
"""
from __future__ import annotations

import casadi as ca

from pumpsim.model_spec.outputs import PUMP_CONTACT_OUTPUTS, VANE_OUTPUTS

from . import pneumatic_model
from .contact_model import contact_vane, housing_contact
from .builder import BuiltModel
from .pneumatic_model import (PLENUM_ENERGIES, GasBuilder, budget_rates, cell_geometry,
                              cell_geometry_function, energy_rows, flat, gas_flows, gas_state,
                              implicit_rates, motor_drive, parameter_symbols, plenum_energy_rows,
                              plenum_state)

QUAD_NAMES = pneumatic_model.QUAD_NAMES + ("contact_work", "load_work")
VANE_GAS_OUTPUTS = ("sddot", "torque_share", "torque_slope", "normal", "slot1", "slot2", "bottom",
                    "penetration", "alpha", "tip_slip", "kinetic_energy", "potential_energy",
                    "friction_power", "contact_power", "load_power", "n_consistent", "ambiguity",
                    "position_residual")


def state_names(N):
    return (["theta", "omega", "current"] + [f"mass_{i}" for i in range(N)]
            + [f"energy_{i}" for i in range(N)] + ["inlet_mass", "exhaust_mass", "booster_mass"]
            + [f"s_{i}" for i in range(N)] + [f"sdot_{i}" for i in range(N)]
            + list(PLENUM_ENERGIES) + ["reed_lift", "reed_rate"])


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
    b = GasBuilder(structure)
    N = structure.vanes
    vane_map = vane_gas_function(b).map(N)
    point_map = contact_point_function(b).map(N)
    cell_rates = b.cell_function(rates=True)
    p, P = parameter_symbols(b)
    phis, facs = b.slot_angles(p), b.factors(p)
    nx = len(state_names(N))
    x = ca.MX.sym("x", nx)
    theta, omega, cur = x[0], x[1], x[2]
    m, U = x[3:3 + N], x[3 + N:3 + 2 * N]
    m_in, m_ex, m_b, U_in, U_ex = plenum_state(x, N)
    s, sd = x[6 + 2 * N:6 + 3 * N], x[6 + 3 * N:6 + 4 * N]
    xr, vr = x[nx - 2], x[nx - 1]
    alpha, alphadot, delta = point_map(theta, omega, s.T, sd.T, phis, p)
    V, dVdt, lin, lex, wall, exposed, vvol = cell_rates(theta, s, alpha.T, sd, alphadot.T, omega, p)
    gs = gas_state(P, m, U, V, m_in, m_ex, m_b, U_in, U_ex)
    lift_gap = ca.fmax(-delta.T, 0.0)  # a lifted vane's tip gap joins its two cells
    fl = gas_flows(P, N, gs, lin, lex, exposed, xr, vr, lift_gap)
    # mechanics: the drive torque each vane needs at omegadot, gas loads included
    p_trail = ca.vertcat(*[gs["pc"][fl["prev"][i]] for i in range(N)])
    Ir, tb = P("rotor.inertia"), P("operation.bearing_torque")

    def required(wd):
        o = vane_map(theta, omega, wd, s.T, sd.T, phis, facs, gs["pc"].T, p_trail.T, gs["p_slot"], p)
        od = dict(zip(VANE_GAS_OUTPUTS, o))
        return Ir * wd + tb + ca.sum2(od["torque_share"]), od

    drive = motor_drive(P, omega, cur, required, Ir, P("motor.inertia"))
    od = drive["outputs"]
    xdot = ca.vertcat(omega, drive["omegadot_used"], drive["current_rate"], fl["dm"],
                      energy_rows(P, N, gs, fl, dVdt, wall), fl["dm_in"], fl["dm_ex"], fl["dm_b"],
                      sd, od["sddot"].T, plenum_energy_rows(N, gs, fl), fl["xr_dot"], fl["vr_dot"])
    gas_power = -ca.dot(gs["pc"], dVdt) - gs["p_slot"] * P("vane.thickness") * gs["W"] * ca.sum1(sd)
    fric_power = ca.sum2(od["friction_power"]) + tb * omega
    qdot = budget_rates(P, cur, omega, drive, fl, gas_power, fric_power,
                        ca.sum2(od["contact_power"]), ca.sum2(od["load_power"]))
    rhs, jac, wd = implicit_rates(x, xdot, qdot, drive, p)
    outs = _outputs(P, omega, cur, s, sd, (m, m_in, m_ex, m_b), (V, dVdt, lin, lex, vvol), gs, fl, drive, od,
                    gas_power, fric_power)
    out_s = ca.Function("outputs_at", [x, drive["omegadot_symbol"], p],
                        [outs[k] for k in PUMP_CONTACT_OUTPUTS])
    out_fn = flat(ca.Function("pump_outputs", [x, p], out_s(x, wd, p), ["x", "p"],
                              list(PUMP_CONTACT_OUTPUTS)))
    cells = cell_geometry_function(cell_geometry(b, p, phis), p)
    fns = {f.name(): f for f in (rhs, jac, out_fn, cells, _constrained_state(b, p, phis, facs))}
    return BuiltModel(structure, b.params, fns)


def _outputs(P, omega, cur, s, sd, masses, cells, gs, fl, drive, od, gas_power, fric_power) -> dict:
    """pump_outputs' rows by name (PUMP_CONTACT_OUTPUTS) from the state's parts, the cells'
    geometry (V, dV/dt, port lengths, vane volume), the gas, the flows and the drive."""
    m, m_in, m_ex, m_b = masses
    V, dVdt, lin, lex, vvol = cells
    tau, r_s = drive["torque"], drive["residual"]
    safe_omega = ca.if_else(ca.fabs(omega) > 1e-9, omega, 1.0)  # per-radian outputs at rest: 0
    at_rest = ca.fabs(omega) <= 1e-9
    return dict(
        torque=tau, omegadot=drive["omegadot_used"], current=cur, pressure=gs["pc"], volume=V,
        temperature=gs["Tc"], dvolume=ca.if_else(at_rest, 0 * dVdt, dVdt / safe_omega),
        inlet_pressure=gs["p_in"], exhaust_pressure=gs["p_ex"], booster_pressure=gs["p_b"],
        slot_pressure=gs["p_slot"], gas_torque=ca.if_else(at_rest, 0.0, gas_power / safe_omega),
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


def _constrained_state(b, p, phis, facs):
    """constrained_state(theta, omega): Model 2's vane positions, sliding speeds and normal
    forces (no gas), where the runtime starts the vanes on the housing."""
    th, w = ca.MX.sym("theta"), ca.MX.sym("omega")
    oc = b.vane_constrained().map(b.st.vanes)(th, w, 0.0, phis, facs, p)
    return ca.Function("constrained_state", [th, w, p],
                       [oc[VANE_OUTPUTS.index(k)].T for k in ("s", "sdot", "normal")],
                       ["theta", "omega", "p"], ["s", "sdot", "normal"])
