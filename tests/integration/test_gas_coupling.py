"""Gas loads on the vanes (spec §8): the mechanics with equal pressures is today's model, the
loads' virtual power is exactly sum p dV/dt, and the shaft, gas, friction and motor energies
balance over a revolution and a run-up."""
import math

import numpy as np
import pytest

from pumpsim.config import as_array
from pumpsim.kernels import load_kernels
from pumpsim.pneumatics import run
from pumpsim.kernels.pneumatic import kernels, parameter_vector
from pumpsim.kernels import inverse_dynamics
from tests.pneumatic_helpers import evp_config, speed_config
from tests.tolerances import EQUAL_PRESSURE_REL, GAS_BUDGET_ATOL, GAS_BUDGET_RTOL, GAS_ENERGY_REL, LOAD_POWER_REL, MOTOR_RESIDUAL_ABS



def _states(cfg, k, p, theta, omega, pressures, slot=None):
    """States with given cell pressures at the gas temperature (manifold, port, booster at 1 bar)."""
    v = dict(zip([q.name for q in __import__("pumpsim.model_spec.parameters", fromlist=["x"]).pneumatic_layout(k.structure)], p))
    R, g, T = v["gas.gas_constant"], v["gas.gamma"], v["gas.temperature"]
    X = []
    for th, pc in zip(theta, pressures):
        V = np.asarray(k["cell_geometry"](th, p)[0]).ravel()
        X.append(np.concatenate([[th, omega, 0.0], pc * V / (R * T), pc * V / (g - 1),
                                 [1e5 * v["ports.inlet_volume"] / (R * T),
                                  1e5 * v["ports.exhaust_volume"] / (R * T),
                                  1e5 * v["booster.volume"] / (R * T),
                                  1e5 * v["ports.inlet_volume"] / (g - 1),
                                  1e5 * v["ports.exhaust_volume"] / (g - 1), 0.0, 0.0]]))
    return np.array(X)


@pytest.mark.parametrize("changes,pressure", [
    ({}, 0.0),
    ({"rotor.slot_tilt": 0.2, "housing.shape": "ellipse", "housing.radius": None, "housing.a": 0.0235,
      "housing.b": 0.0220, "housing.center": [0.0008, 0.0003]}, 0.0),
    # equal pressures everywhere (radial slots): the loads cancel. Flat tips: every flank reaches
    # past the rotor (the round tips' retracted case: the next test)
    ({"vane.tip_radius": 0.0}, 1.0e5),
])
def test_equal_pressures_give_todays_torque(changes, pressure):
    gas, mech, _ = _equal_pressures(changes, pressure)
    scale = np.sqrt(np.mean(mech["torque"] ** 2))
    assert np.max(np.abs(gas["torque"] - mech["torque"])) <= EQUAL_PRESSURE_REL * scale
    assert np.max(np.abs(gas["normal"] - mech["normal"].T)) <= EQUAL_PRESSURE_REL * np.abs(mech["normal"]).max()


def test_equal_pressures_push_only_a_retracted_round_tip_out():
    """The EVP's full-round tips: where a flank ends inside the rotor the cells are bounded by the
    rotor circle (spec §8) and only the cap outside it is loaded, so equal pressures in the cells
    and under the vane push that vane out by p W (h - chord): it presses harder on the housing.
    Every other vane is loaded with nothing (at constant speed each vane's reaction is its own)."""
    gas, mech, exposed = _equal_pressures({}, 1.0e5)
    dn = gas["normal"] - mech["normal"].T
    out = exposed > 0
    assert out.sum() > 0.6 * out.size and (~out).sum() > 0.1 * out.size
    assert np.max(np.abs(dn[out])) <= EQUAL_PRESSURE_REL * np.abs(mech["normal"]).max()
    assert np.all(dn[~out] > 1e-3 * np.abs(mech["normal"]).max())


def _equal_pressures(changes, pressure):
    """pumpsim's torque and housing normals at equal cell and slot pressures against today's
    mechanics (no gas) over a revolution at 400 rad/s; and each vane's exposed flank length."""
    cfg = speed_config(400.0, **{"vane.slot_pressure": pressure, **changes})
    k = kernels(cfg)
    p = parameter_vector(cfg)
    theta = np.linspace(0, 2 * math.pi, 37)
    X = _states(cfg, k, p, theta, 400.0, [np.full(cfg.vanes, pressure)] * theta.size)
    gas = run.evaluate_outputs(k, X, p, ["torque", "normal"])
    pv = cfg.parameters("constrained")
    mech = inverse_dynamics(load_kernels(pv.structure), as_array(pv), theta, 400.0, 0.0)
    names = k["cell_geometry"].name_out()
    exposed = np.array([np.asarray(k["cell_geometry"](t, p)[names.index("exposed")]).ravel() for t in theta])
    return gas, mech, exposed


def test_load_power_is_sum_p_dV():
    """Reynolds: the gas forces on flanks, tips and slot bottoms do exactly sum p_i dV_i/dt plus
    the slot-bottom p_slot h W sum sdot, for any pressures and housing."""
    cfg = speed_config(400.0, **{"rotor.slot_tilt": 0.15, "housing.center": [0.0028, 0.0006]})
    k, p = kernels(cfg), parameter_vector(cfg)
    rng = np.random.default_rng(3)
    theta = np.linspace(0, 2 * math.pi, 29)
    X = _states(cfg, k, p, theta, 400.0, rng.uniform(2e4, 2e5, (theta.size, cfg.vanes)))
    o = run.evaluate_outputs(k, X, p, ["load_power", "gas_power"])
    scale = np.abs(o["gas_power"]).max()
    assert scale > 1.0
    assert np.max(np.abs(o["load_power"] + o["gas_power"])) <= LOAD_POWER_REL * scale


def _one_revolution(cfg, rtol=GAS_BUDGET_RTOL):
    """Constant speed: two revolutions to settle, then one revolution's budgets."""
    T = 2 * math.pi / cfg.speed
    r0 = run.integrate(cfg, 2 * T, 200 / T, rtol=1e-8, atol=1e-10)
    r = run.integrate(cfg, T, 400 / T, x0=r0.states[-1], rtol=rtol, atol=GAS_BUDGET_ATOL)
    q = dict(zip(run.QUAD_NAMES, r.quad[-1]))
    ke = r.outputs["kinetic_energy"]
    return q, ke[-1] - ke[0], r


@pytest.mark.parametrize("mu", [0.0, 0.15])
def test_shaft_work_is_gas_plus_friction_work_over_a_revolution(mu):
    cfg = speed_config(350.0, **{"gas.heat_transfer": 0.0, "friction.housing.static": mu * 1.07,
                                 "friction.housing.dynamic": mu})
    q, dke, r = _one_revolution(cfg)
    assert q["gas_work"] > 0.05  # J per revolution: compression work is being done
    lhs = q["shaft_work"]
    assert lhs == pytest.approx(q["gas_work"] + q["friction_work"] + dke, rel=GAS_ENERGY_REL)
    if mu == 0.0:  # mean torque = gas work per radian
        mean_torque = lhs / (2 * math.pi)
        assert mean_torque == pytest.approx(q["gas_work"] / (2 * math.pi), rel=GAS_ENERGY_REL)
        assert q["friction_work"] == 0.0


def test_motor_energy_balance_during_run_up():
    """V i = R i^2 + L i di/dt + k omega i and k i = tau_f + I_m omegadot + tau_shaft, so
    E_electrical = E_copper + L i^2/2 + E_motor_friction + I_m omega^2/2 + E_shaft; and the shaft
    work = gas + friction work + the pump's kinetic energy."""
    cfg = evp_config()
    p = parameter_vector(cfg)
    r = run.integrate(cfg, 0.05, 4000, p=p, rtol=GAS_BUDGET_RTOL, atol=GAS_BUDGET_ATOL)
    q = dict(zip(run.QUAD_NAMES, r.quad[-1]))
    v = cfg.pneumatic.values
    w, i = r.states[-1, 1], r.states[-1, 2]
    assert w > 200.0
    motor = q["copper_loss"] + 0.5 * v["motor.inductance"] * i**2 + q["motor_friction_work"] \
        + 0.5 * v["motor.inertia"] * w**2 + q["shaft_work"]
    assert q["electrical_energy"] == pytest.approx(motor, rel=GAS_ENERGY_REL)
    pump_ke = 0.5 * cfg.values["rotor.inertia"] * w**2 + r.outputs["kinetic_energy"][-1]
    assert q["shaft_work"] == pytest.approx(q["gas_work"] + q["friction_work"] + pump_ke, rel=GAS_ENERGY_REL)
    assert np.max(np.abs(r.outputs["motor_residual"])) < MOTOR_RESIDUAL_ABS
