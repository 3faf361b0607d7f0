"""The inlet manifold and the exhaust port as volumes with their own mass and energy (spec §8's
network of openings, each flow at its upstream temperature, in the limit of vanishing volumes):
the first law over the whole gas network, at single states (to rounding) and over a run (to the
integrator's tolerance), and the figures' convergence as the two volumes shrink."""
import math

import numpy as np
import pytest

from pumpsim.kernels.pneumatic import kernels, parameter_vector
from pumpsim.pneumatics import run
from tests.pneumatic_helpers import evp_config, speed_config
from tests.tolerances import GAS_BUDGET_ATOL, GAS_BUDGET_RTOL, GAS_ENERGY_REL


def _parts(k, p):
    """Named parts of the state layout (run.state_names) and the parameters."""
    N = k.structure.vanes
    v = dict(zip(run._names(k.structure), p))
    i = {n: j for j, n in enumerate(run.state_names(N))}
    return N, v, i


def _network_energy(k, p, X):
    """Internal energy of the gas outside the booster (cells, manifold, exhaust port), per row."""
    N, _, i = _parts(k, p)
    return X[:, 3 + N:3 + 2 * N].sum(1) + X[:, i["inlet_energy"]] + X[:, i["exhaust_energy"]]


def _random_states(k, p, rng, n=12):
    """States off equilibrium: cells 20-150 kPa at 250-400 K, manifold and exhaust port each at its
    own pressure and temperature, the booster above the manifold (the hose open) and the port above
    the atmosphere (the valve open, by turns partly and fully)."""
    N, v, i = _parts(k, p)
    R, g = v["gas.gas_constant"], v["gas.gamma"]
    X = []
    for j in range(n):
        th = rng.uniform(0, 2 * math.pi)
        x = run.initial_state(evp_config(), k, p, theta0=th, omega0=rng.uniform(200, 600))
        V = np.asarray(k["cell_geometry"](th, p)[0]).ravel()
        pc, Tc = rng.uniform(20e3, 150e3, N), rng.uniform(250, 400, N)
        x[3:3 + N], x[3 + N:3 + 2 * N] = pc * V / (R * Tc), pc * V / (g - 1)
        p_in, T_in = rng.uniform(20e3, 90e3), rng.uniform(230, 330)
        p_ex, T_ex = v["gas.atmosphere"] + rng.uniform(0, 8e3), rng.uniform(290, 450)
        p_b = p_in + rng.uniform(0, 2e3)
        for name, pr, T, vol in (("inlet", p_in, T_in, "ports.inlet_volume"),
                                 ("exhaust", p_ex, T_ex, "ports.exhaust_volume")):
            x[i[f"{name}_mass"]] = pr * v[vol] / (R * T)
            x[i[f"{name}_energy"]] = pr * v[vol] / (g - 1)
        x[i["booster_mass"]] = p_b * v["booster.volume"] / (R * v["gas.temperature"])
        x[2] = rng.uniform(0, 20)
        X.append(x)
    return np.array(X), (R, g)


def test_network_energy_rows_close_the_first_law_at_any_state():
    """d/dt of the cells', manifold's and exhaust port's internal energy = the enthalpy the hose
    brings in at gas.temperature - what the valve takes out at the exhaust port's temperature -
    sum p dV/dt + the wall heat into the cells; and the masses' rates sum to the booster leak
    less the valve flow. An identity of the rows (each flow's enthalpy leaves one volume and
    enters the next): to rounding."""
    cfg = evp_config(**{"gas.heat_transfer": 300.0})
    k, p = kernels(cfg), parameter_vector(cfg)
    N, v, i = _parts(k, p)
    X, (R, g) = _random_states(k, p, np.random.default_rng(7))
    cp = g * R / (g - 1)
    T0 = v["gas.temperature"]
    opened = 0
    for x in X:
        xdot = np.asarray(k["pump_rhs"](x, p)[0]).ravel()
        o = {n: np.asarray(a).ravel() for n, a in zip(k["pump_outputs"].name_out(), k["pump_outputs"](x, p))}
        geo = dict(zip(k["cell_geometry"].name_out(), k["cell_geometry"](x[0], p)))
        T_ex = x[i["exhaust_energy"]] / (x[i["exhaust_mass"]] * R / (g - 1))
        Tc = o["temperature"]
        wall = np.asarray(geo["wall_area"]).ravel()
        heat = v["gas.heat_transfer"] * wall @ (v["gas.wall_temperature"] - Tc)
        work = -o["pressure"] @ (np.asarray(geo["dvolume"]).ravel() * x[1])
        f_hose, f_valve = float(o["hose_flow"][0]), float(o["valve_flow"][0])
        assert f_hose >= 0 and f_valve >= 0  # the check valves pass forward flow only
        opened += f_hose > 0 and f_valve > 0
        dU = xdot[3 + N:3 + 2 * N].sum() + xdot[i["inlet_energy"]] + xdot[i["exhaust_energy"]]
        expect = cp * T0 * f_hose - cp * T_ex * f_valve + work + heat
        # rounding: relative to every flow's size (the window and leak flows cancel in the sums)
        flows = f_hose + f_valve + sum(np.abs(o[n]).sum() for n in ("inlet_flow", "exhaust_flow", "leak_flow"))
        assert dU == pytest.approx(expect, abs=1e-12 * (cp * 500.0 * flows + abs(work) + abs(heat)))
        dm = xdot[3:3 + N].sum() + sum(xdot[i[n]] for n in ("inlet_mass", "exhaust_mass", "booster_mass"))
        assert dm == pytest.approx(float(o["booster_leak"][0]) - f_valve, abs=1e-12 * flows)
    assert opened >= len(X) // 2  # the hose and valve terms are exercised


def test_network_first_law_holds_over_a_run():
    """Integrated, adiabatic walls, the exhaust valve held shut and no slot-bottom gas (so that
    every energy crossing the network's boundary is in the budgets): the internal energy of cells,
    manifold and exhaust port grows by the enthalpy the hose brought in (gas.temperature times the
    mass the booster lost, its leak off) plus the gas work done on the cells (gas_work), to the
    integrator's tolerance. The manifold's and the exhaust port's gas leave gas.temperature."""
    cfg = speed_config(300.0, **{"gas.heat_transfer": 0.0, "valve.cracking": 1e7, "booster.leak": 0.0,
                                 "vane.slot_pressure": 0.0})
    k, p = kernels(cfg), parameter_vector(cfg)
    N, v, i = _parts(k, p)
    R, g, T0 = v["gas.gas_constant"], v["gas.gamma"], v["gas.temperature"]
    r = run.integrate(cfg, 0.05, 2000, rtol=GAS_BUDGET_RTOL, atol=GAS_BUDGET_ATOL)
    X, q = r.states, dict(zip(run.QUAD_NAMES, r.quad[-1]))
    assert q["valve_damping_work"] == 0.0 and np.all(r.outputs["valve_flow"] == 0.0)
    dU = _network_energy(k, p, X[-1:])[0] - _network_energy(k, p, X[:1])[0]
    hose = g * R / (g - 1) * T0 * (X[0, i["booster_mass"]] - X[-1, i["booster_mass"]])
    assert hose > 0.05 * abs(q["gas_work"]) and q["gas_work"] > 1.0  # both terms count
    assert dU == pytest.approx(hose + q["gas_work"], rel=GAS_ENERGY_REL)
    T_ex = X[:, i["exhaust_energy"]] / (X[:, i["exhaust_mass"]] * R / (g - 1))
    T_in = X[:, i["inlet_energy"]] / (X[:, i["inlet_mass"]] * R / (g - 1))
    # the port heats (adiabatic compression of a closed discharge), the manifold first cools
    # (expanding into the cells) and then warms with the leaks' hot back-flow
    assert T_ex.max() > T0 + 100 and T_in.min() < T0 - 1 and T_in.max() > T0 + 100


# the plenums' volumes scaled by 1, 1/4, 1/16: over the EVP example's first 0.2 s the figures
# move linearly in the volume toward the network without volumes (the differences fall ~4x per step)
SCALES = (1.0, 0.25, 0.0625)


@pytest.mark.slow
def test_figures_converge_as_the_manifold_and_exhaust_port_shrink():
    base = evp_config()
    vin, vex = base.pneumatic.values["ports.inlet_volume"], base.pneumatic.values["ports.exhaust_volume"]
    figs = []
    for s in SCALES:
        cfg = evp_config(**{"ports.inlet_volume": vin * s, "ports.exhaust_volume": vex * s})
        r = run.integrate(cfg, 0.2, 2000, rtol=1e-7, atol=1e-8)
        figs.append(np.array([r.outputs["booster_pressure"][-1], r.quad[-1, 0], np.mean(r.outputs["current"])]))
    d1, d2 = np.abs(figs[1] - figs[0]), np.abs(figs[2] - figs[1])
    # first order in the volume: each quarter of it moves a figure ~4x less than the one before
    assert np.all((d2 > d1 / 6) & (d2 < d1 / 2.5)), (d1, d2)
