"""`pumpsim simulate` (Model 2) on a config with the spec §8 gas tables runs the gas-coupled model:
the spec §7 columns plus the §8 ones, the vanes where the mechanics puts them, and a torque whose
work is the gas work plus the friction work. (Before, it silently returned the mechanical torque.)"""
import math
import subprocess
import sys

import numpy as np
import pytest

from pumpsim import simulate
from tests.conftest import ROOT
from tests.pneumatic_helpers import speed_config
from tests.tolerances import EQUAL_PRESSURE_REL, GAS_BUDGET_ATOL, GAS_BUDGET_RTOL, GAS_ENERGY_REL

EVP = "examples/evp_booster.toml"


def test_simulate_on_a_gas_config_runs_the_gas_model():
    cfg = speed_config(350.0, **{"gas.heat_transfer": 0.0})
    res = simulate(cfg, duration=2 * 2 * math.pi / 350.0, rate=20000, rtol=GAS_BUDGET_RTOL, atol=GAS_BUDGET_ATOL)
    N = cfg.vanes
    names = res.column_names()
    assert names[:4] == ["time", "angle", "speed", "torque"]
    assert {f"{c}_{i}" for i in range(N) for c in ("s", "sdot", "normal", "slot1", "slot2", "pressure",
                                                    "volume", "temperature")} <= set(names)
    assert "booster_pressure" in names and "current" in names
    # Model 2 geometry: the vane positions and speeds are the mechanical model's at the same angle
    mech = simulate(speed_config(350.0), duration=res.time[-1], rate=20000)
    L = cfg.values["vane.length"]
    assert np.max(np.abs(res["s_1"] - mech["s_1"])) <= EQUAL_PRESSURE_REL * L
    assert np.max(np.abs(res["sdot_2"] - mech["sdot_2"])) <= EQUAL_PRESSURE_REL * 350.0 * L
    # two whole revolutions at constant speed: the vanes' kinetic energy is back where it started,
    # so the shaft work is the gas work plus the friction work (and valve damping)
    q = res.budgets
    assert q["gas_work"] > 0.1 * q["shaft_work"]  # the gas is a real share: not the mechanical torque
    assert q["shaft_work"] == pytest.approx(q["gas_work"] + q["friction_work"] + q["valve_damping_work"],
                                            rel=GAS_ENERGY_REL)
    assert np.mean(res["torque"]) > np.mean(mech["torque"])  # compression costs torque


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pumpsim", *args], capture_output=True, text=True, cwd=ROOT)


def test_simulate_cli_on_the_evp_example_writes_the_gas_columns(tmp_path):
    out = tmp_path / "m2.csv"
    r = _cli("simulate", EVP, "--duration", "0.01", "--rate", "4000", "--out", str(out))
    assert r.returncode == 0, r.stderr
    header = out.read_text().splitlines()[0].split(",")
    assert "booster_pressure" in header and "pressure_3" in header and "penetration_0" not in header
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape[0] == 41
    assert "motor drive" in r.stdout and "work: shaft" in r.stdout


def test_simulate_cli_gas_model_refuses_other_integrators(tmp_path):
    out = tmp_path / "m2.csv"
    r = _cli("simulate", EVP, "--method", "idas", "--out", str(out))
    assert r.returncode == 2 and "cvodes" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_simulate_cli_gas_model_refuses_max_step(tmp_path):
    """--max-step shapes the mechanical integrators only; on a gas config it was silently ignored."""
    out = tmp_path / "m2.csv"
    r = _cli("simulate", EVP, "--duration", "0.002", "--max-step", "1e-6", "--out", str(out))
    assert r.returncode == 2 and "max_step" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_simulate_gas_numerical_failure_says_where_and_exits_1(tmp_path):
    """A numerical failure names the time and the state; under `simulate` it is not called a
    pump-down (the message came from the pump-down's integrator loop)."""
    out = tmp_path / "m2.csv"
    r = _cli("simulate", EVP, "--duration", "0.01", "--max-steps", "5", "--out", str(out))
    assert r.returncode == 1 and "Traceback" not in r.stderr and not out.exists()
    assert "gas model's integration failed between t = 0 s" in r.stderr and "theta" in r.stderr
    assert "pump-down" not in r.stderr


def test_simulate_figure_of_a_gas_run_has_the_cell_pressures_and_current():
    """The figure of a gas run adds the cell and booster pressures (and, with the motor, the
    current); a mechanical run's figure has neither."""
    import matplotlib.pyplot as plt

    from pumpsim.report.simulation import simulation_figure
    from tests.pneumatic_helpers import evp_config

    def labels(res):
        fig = simulation_figure(res)
        out = {ax.get_ylabel() for ax in fig.axes}
        plt.close(fig)
        return out

    gas = labels(simulate(evp_config(), duration=0.004, rate=20000))
    assert {"cell pressure [kPa]", "motor current [A]"} <= gas
    assert "motor current [A]" not in labels(simulate(speed_config(350.0), duration=0.004, rate=20000))
    mech = labels(simulate(speed_config(350.0, **{t: None for t in ("gas", "ports", "valve", "leak", "booster",
                                                                   "motor", "vane.slot_pressure")}),
                           duration=0.004, rate=20000))
    assert "cell pressure [kPa]" not in mech
