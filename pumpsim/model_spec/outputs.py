"""Names, units and shapes of every output the compiled kernels export.

codegen builds each exported function with exactly these input and output names (the build fails
on a function or output not declared here); the runtime reshapes a mapped kernel's outputs by the
shape declared here -- a new output gets its shape here, not by a guess in the runtime.

Shapes: "sample" -- one value per sample; "vane" (or "cell") -- one value per vane (cell) and sample (the runtime
returns an (n_vanes, n_samples) array); "other" -- vectors and matrices the runtime reads directly
(states, Jacobians, the report form), never through the per-sample evaluator.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Output:
    name: str
    unit: str
    shape: str  # sample | vane | other
    doc: str = ""


def _declare(*rows) -> dict:
    return {name: Output(name, unit, shape, doc) for name, unit, shape, doc in rows}


OUTPUTS = _declare(
    ("torque", "N m", "sample", "drive torque (inverse dynamics), the measured shaft torque"),
    ("omegadot", "rad/s^2", "sample", "rotor acceleration (forward dynamics)"),
    ("torque_residual", "N m", "sample", "rotor-equation residual after the Newton solve on omegadot"),
    ("s", "m", "vane", "vane extension from the slot bottom"),
    ("sdot", "m/s", "vane", "vane sliding velocity"),
    ("sddot", "m/s^2", "vane", "vane sliding acceleration"),
    ("alpha", "rad", "vane", "housing-curve parameter of the tip contact"),
    ("alphadot", "rad/s", "vane", "its rate"),
    ("normal", "N", "vane", "housing normal force on the tip"),
    ("slot1", "N", "vane", "slot-wall force at the vane's bottom end"),
    ("slot2", "N", "vane", "slot-wall force at the slot mouth"),
    ("bottom", "N", "vane", "slot-bottom contact force (Model 1)"),
    ("penetration", "m", "vane", "housing penetration, > 0 is interference (Model 1)"),
    ("penetration_rate", "m/s", "vane", "its exact time derivative (Model 1)"),
    ("torque_share", "N m", "vane", "the vane's share of the drive torque"),
    ("torque_slope", "kg m^2", "vane", "d torque_share / d omegadot on the selected contact sides"),
    ("tip_slip", "m/s", "vane", "tip slip speed along the housing"),
    ("mu_housing", "-", "vane", "vane-housing friction coefficient in use"),
    ("mu_slot", "-", "vane", "slot friction coefficient in use"),
    ("kinetic_energy", "J", "vane", "vane kinetic energy"),
    ("potential_energy", "J", "vane", "elastic energy in the penalty contacts (Model 1)"),
    ("n_consistent", "-", "vane", "number of consistent contact-side sets (1 unless a paradox)"),
    ("ambiguity", "-", "vane", "force spread between consistent sets, relative to the force scale"),
    ("position_residual", "m", "vane", "closure of the position solve"),
    ("xdot", "-", "other", "state derivative"),
    ("jac_xdot_x", "-", "other", "d xdot / d x"),
    ("jac_xdot_omegadot", "-", "other", "d xdot / d omegadot"),
    ("jac_xdot_torque", "-", "other", "d xdot / d torque"),
    ("phi", "m", "other", "constraint Phi(q)"),
    ("phi_q", "-", "other", "constraint Jacobian"),
    ("gamma", "-", "other", "acceleration right-hand side"),
    ("matrix", "-", "other", "report form [M V; Phi_q 0]"),
    ("rhs", "-", "other", "report form right-hand side"),
    ("point", "m", "other", "housing point"),
    ("normal_vector", "-", "other", "housing outward normal"),
    ("radius", "m", "other", "housing polar radius"),
    ("curvature", "-", "other", "housing curvature sign"),
    # spec §8 (pneumatic model): "sample" one per sample, "cell" one per cell and sample
    ("current", "A", "sample", "motor current"),
    ("pressure", "Pa", "cell", "cell pressure"),
    ("volume", "m^3", "cell", "cell volume"),
    ("temperature", "K", "cell", "cell gas temperature"),
    ("dvolume", "m^3/rad", "cell", "d volume / d theta"),
    ("inlet_pressure", "Pa", "sample", "inlet manifold pressure"),
    ("exhaust_pressure", "Pa", "sample", "exhaust port pressure (under the valve)"),
    ("booster_pressure", "Pa", "sample", "booster pressure"),
    ("slot_pressure", "Pa", "sample", "pressure under the vanes"),
    ("gas_torque", "N m", "sample", "-(sum p_i dV_i/dtheta + p_slot dV_slot/dtheta): shaft torque into gas"),
    ("friction_power", "W", "sample", "vane-tip, slot and bearing friction power"),
    ("gas_power", "W", "sample", "power into the gas (-sum p dV/dt)"),
    ("load_power", "W", "sample", "virtual power of the gas loads on vanes and rotor"),
    ("inlet_flow", "kg/s", "cell", "manifold -> cell through the inlet window"),
    ("exhaust_flow", "kg/s", "cell", "cell -> exhaust port through the exhaust window"),
    ("leak_flow", "kg/s", "cell", "leak across vane j from cell j-1 to cell j"),
    ("hose_flow", "kg/s", "sample", "booster -> manifold through hose and check valve"),
    ("booster_leak", "kg/s", "sample", "atmosphere -> booster"),
    ("valve_flow", "kg/s", "sample", "exhaust port -> atmosphere through the valve"),
    ("reed_force", "N", "sample", "net opening force on the reed"),
    ("mass_total", "kg", "sample", "gas in cells, manifold, exhaust port and booster"),
    ("inlet_length", "m", "cell", "arc length of the inlet window a cell covers"),
    ("exhaust_length", "m", "cell", "arc length of the exhaust window a cell covers"),
    ("vane_volume", "m^3", "cell", "vane volume outside the rotor (one per vane)"),
    ("exposed", "m", "cell", "flank length of a vane outside the rotor, the end-face leak's length "
     "(one per vane)"),
    ("wall_area", "m^2", "cell", "cell wall area for the heat exchange (end faces, housing and rotor "
     "arcs, exposed flanks)"),
    ("motor_residual", "N m", "sample", "motor-drive torque residual after the omegadot Newton"),
    ("mdot", "kg/s", "sample", "orifice mass flow, side 1 -> 2"),
    ("contact_power", "W", "sample", "power of the penalty contacts on their surroundings: elastic "
     "storage + contact damping (Model 1 with gas)"),
    ("volume_rate", "m^3/s", "cell", "d volume / dt (Model 1 with gas: the vanes move on their own)"),
    ("qdot", "-", "other", "rates of the energy and mass budgets"),
    ("jac_qdot_x", "-", "other", "d qdot / d x"),
    ("geometry", "-", "other", "the cell geometry the right-hand side reads at theta (a table row)"),
    ("dgeometry", "-", "other", "d geometry / d theta"),
)

# one vane's outputs, in the order the vane functions return them
VANE_OUTPUTS = (
    "s", "sdot", "sddot", "alpha", "alphadot", "normal", "slot1", "slot2", "torque_share",
    "tip_slip", "mu_housing", "mu_slot", "kinetic_energy", "n_consistent", "ambiguity",
    "position_residual", "torque_slope",
)
CONTACT_VANE_OUTPUTS = (
    "sddot", "normal", "slot1", "slot2", "bottom", "penetration", "penetration_rate", "alpha",
    "tip_slip", "mu_housing", "mu_slot", "kinetic_energy", "potential_energy", "torque_share",
    "torque_slope", "n_consistent", "ambiguity", "position_residual",
)


@dataclass(frozen=True)
class Signature:
    inputs: tuple
    outputs: tuple


_CONSTRAINED = {
    "inverse_dynamics": Signature(("theta", "omega", "omegadot", "p"), ("torque", *VANE_OUTPUTS)),
    "forward_dynamics": Signature(("theta", "omega", "torque", "p"),
                                  ("omegadot", "torque_residual", *VANE_OUTPUTS)),
    "ode_rhs": Signature(("x", "torque", "p"), ("xdot",)),
    "positions": Signature(("theta", "p"), ("s", "alpha", "position_residual")),
    "constraint": Signature(("q", "p"), ("phi",)),
    "constraint_jacobian": Signature(("q", "p"), ("phi_q",)),
    "acceleration_rhs": Signature(("q", "qd", "p"), ("gamma",)),
    "dynamic_system": Signature(("q", "qd", "sigma", "omegadot", "p"), ("matrix", "rhs")),
}
_CONTACT = {
    "contact_dynamics": Signature(("theta", "omega", "omegadot", "s", "sdot", "p"),
                                  ("torque", *CONTACT_VANE_OUTPUTS)),
    "contact_forward": Signature(("theta", "omega", "torque", "s", "sdot", "p"),
                                 ("omegadot", "torque_residual", *CONTACT_VANE_OUTPUTS)),
    "ode_speed": Signature(("x", "omegadot", "p"), ("xdot",)),
    "ode_speed_jac": Signature(("x", "omegadot", "p"), ("jac_xdot_x", "jac_xdot_omegadot")),
    "ode_torque": Signature(("x", "torque", "p"), ("xdot",)),
    "ode_torque_jac": Signature(("x", "torque", "p"), ("jac_xdot_x", "jac_xdot_torque")),
    "constrained_state": Signature(("theta", "omega", "p"), ("s", "sdot", "normal")),
}
_BOTH = {"housing_curve": Signature(("alpha", "p"), ("point", "normal_vector", "radius", "curvature"))}
# spec §8: cells, gas, booster, motor (pump_outputs: per sample, or (n, N) per cell / vane)
PUMP_OUTPUTS_COMMON = (
    "torque", "omegadot", "current", "pressure", "volume", "temperature", "dvolume",
    "inlet_pressure", "exhaust_pressure", "booster_pressure", "slot_pressure", "gas_torque",
    "friction_power", "gas_power", "load_power", "kinetic_energy", "normal", "slot1", "slot2",
    "n_consistent", "s", "position_residual", "inlet_flow", "exhaust_flow", "leak_flow",
    "hose_flow", "booster_leak", "valve_flow", "reed_force", "mass_total", "inlet_length",
    "exhaust_length", "vane_volume", "motor_residual",
)
# Model 2 with gas: also the vanes' kinematics and friction coefficients, for the design
# studies' outputs of a config with gas tables (friction split per vane, paradox)
PUMP_OUTPUTS = PUMP_OUTPUTS_COMMON + ("sdot", "tip_slip", "mu_housing", "mu_slot", "ambiguity")
_PNEUMATIC = {
    "cell_geometry": Signature(("theta", "p"), ("volume", "dvolume", "vane_volume", "inlet_length",
                                                "exhaust_length", "s", "alpha", "position_residual",
                                                "exposed", "wall_area")),
    "orifice_flow": Signature(("p1", "T1", "p2", "T2", "area", "p"), ("mdot",)),
    "pump_rhs": Signature(("x", "p"), ("xdot", "qdot")),
    "pump_rhs_jac": Signature(("x", "p"), ("jac_xdot_x", "jac_qdot_x")),
    "pump_outputs": Signature(("x", "p"), PUMP_OUTPUTS),
}
# the right-hand side over a table of the angle-only cell geometry (Model 2 only: with Model 1
# the geometry follows the vanes' own states)
_PNEUMATIC_TABLE = {
    "geometry_table": Signature(("theta", "p"), ("geometry", "dgeometry")),
    "pump_rhs_tab": Signature(("x", "g", "p"), ("xdot", "qdot")),
    "pump_rhs_tab_jac": Signature(("x", "g", "dg", "p"), ("jac_xdot_x", "jac_qdot_x")),
}


# Model 1 with gas (spec §2 and §8): the vanes' own states, contacts and lift-off
PUMP_CONTACT_OUTPUTS = PUMP_OUTPUTS_COMMON + (
    "sdot", "penetration", "bottom", "alpha", "tip_slip", "ambiguity", "potential_energy",
    "contact_power", "volume_rate",
)
_PNEUMATIC_CONTACT = {
    **_PNEUMATIC,
    "pump_outputs": Signature(("x", "p"), PUMP_CONTACT_OUTPUTS),
    "constrained_state": _CONTACT["constrained_state"],
}


def signatures(model: str) -> dict:
    """Exported function name -> Signature for one model ("constrained" | "contact" | "pneumatic"
    | "pneumatic-contact")."""
    if model == "pneumatic":
        return {**_PNEUMATIC, **_PNEUMATIC_TABLE}
    if model == "pneumatic-contact":
        return dict(_PNEUMATIC_CONTACT)
    return {**(_CONTACT if model == "contact" else _CONSTRAINED), **_BOTH}


def shape(name: str) -> str:
    """The declared shape of output `name` (KeyError names the undeclared output)."""
    try:
        return OUTPUTS[name].shape
    except KeyError:
        raise KeyError(f"kernel output '{name}' is not declared in pumpsim/model_spec/outputs.py") from None


def check_signature(model: str, fname: str, inputs, outputs) -> None:
    """Raise ValueError unless function `fname` has exactly the declared input and output names."""
    sig = signatures(model).get(fname)
    if sig is None:
        raise ValueError(f"exported function '{fname}' is not declared in pumpsim/model_spec/outputs.py")
    undeclared = [o for o in outputs if o not in OUTPUTS]
    if tuple(inputs) != sig.inputs or tuple(outputs) != sig.outputs or undeclared:
        raise ValueError(f"'{fname}' exports inputs {list(inputs)} and outputs {list(outputs)}; the "
                         f"contract declares {list(sig.inputs)} and {list(sig.outputs)}")
