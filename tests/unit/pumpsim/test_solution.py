"""One Solution for both models: spec columns and every kernel output by name, computed once."""
import numpy as np
import pytest

import pumpsim
from pumpsim.result import Solution
from pumpsim.result import REPORTED
from pumpsim.kernels import sampled_inverse_dynamics
from pumpsim.motion import speed_profile
from tests.conftest import kernel_and_p, make_config


@pytest.fixture(scope="module")
def ellipse():
    cfg = make_config("ellipse_4vanes")
    return cfg, pumpsim.simulate(cfg, duration=0.004, rate=10000)


def test_outputs_on_first_use_equal_the_kernel_and_are_cached(ellipse):
    cfg, res = ellipse
    assert "kinetic_energy" not in res.extra  # not computed up front
    kern, p, _ = kernel_and_p(cfg)
    theta, omega, omegadot = speed_profile(cfg.angle, cfg.speed, res.time)
    # the kernel simulate runs (the SIMD library where the machine has it; test_fast_kernel holds
    # it against the CasADi map): the reported columns up front, any other output on first use
    direct = sampled_inverse_dynamics(kern, p, theta, omega, omegadot)
    reported = sampled_inverse_dynamics(kern, p, theta, omega, omegadot, ("torque", *REPORTED))
    ke = res["kinetic_energy"]
    assert np.array_equal(ke, direct["kinetic_energy"]) and ke.shape == (4, res.time.size)
    assert res["kinetic_energy"] is ke  # cached
    assert np.array_equal(res["tip_slip_2"], direct["tip_slip"][2])
    assert np.array_equal(res["s_1"], reported["s"][1]) and np.array_equal(res["torque"], reported["torque"])
    assert res.kernel_key == kern.key
    with pytest.raises(KeyError, match="no column or output 'nonsense'"):
        res["nonsense"]


def test_both_models_return_one_solution_type(ellipse):
    cfg, res = ellipse
    contact = pumpsim.simulate(cfg, model="contact", duration=0.001, rate=10000)
    assert type(res) is type(contact) is Solution and pumpsim.SimulationResult is Solution
    assert contact["penetration_0"].shape == contact.time.shape
    assert contact["potential_energy"].shape == (4, contact.time.size)
    assert contact.kernel_key and contact.kernel_key != res.kernel_key


def test_parquet_has_the_csv_columns(ellipse, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    _, res = ellipse
    res.to_parquet(tmp_path / "r.parquet")
    table = pq.read_table(tmp_path / "r.parquet")
    assert table.column_names == res.column_names()
    assert np.array_equal(table.column("torque").to_numpy(), res.torque)
    assert table.schema.metadata[b"kernel_key"].decode() == res.kernel_key
