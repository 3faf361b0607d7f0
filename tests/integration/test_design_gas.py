"""Design studies with the gas model (issue 14, spec §9 gas outputs; §8 tables): the study's
gas_power, pumping_speed and mean_current against the pneumatics API and a full pump-down, the
refusal of gas outputs without §8 tables, and the tip PV's closed form in the contact area."""

import numpy as np
import pytest

from pumpsim import design
from pumpsim.cli import main
from pumpsim.config import load_config
from pumpsim.design.study import study_from_dict
from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.pneumatics import run
from tests.conftest import EXAMPLES
from tests.tolerances import (CLOSED_FORM_REL, GAS_CURRENT_VS_PUMPDOWN_REL, GAS_FLOW_VS_PUMPDOWN_REL,
                              GAS_STUDY_BALANCE_REL, ROUNDING_REL)

EVP = str(EXAMPLES / "evp_booster.toml")
RIG = str(EXAMPLES / "test_rig.toml")

def _full_pumpdown_window(cfg, t0=0.3, t1=0.4):
    """Averages of a full pump-down over [t0, t1]: booster pressure, pumping speed (mass drawn
    from the booster over the gas density there), mean current (electrical energy / V t), gas
    power (gas work / t), mean speed."""
    r = pdm.pumpdown(cfg, duration=t1 + 1e-3)
    t, pb, q = r.time, r.columns["booster_pressure"], r.run.quad
    i0, i1 = np.searchsorted(t, [t0, t1 - 1e-9])
    v = cfg.pneumatic.values
    RT, dt = v["gas.gas_constant"] * v["gas.temperature"], t[i1] - t[i0]
    p_mean = float(np.mean(pb[i0:i1 + 1]))
    mdot = (pb[i0] - pb[i1]) * v["booster.volume"] / RT / dt
    dq = dict(zip(run.QUAD_NAMES, (q[i1] - q[i0]) / dt))
    return p_mean, {"pumping_speed": mdot * RT / p_mean, "gas_power": dq["gas_work"],
                    "mean_current": dq["electrical_energy"] / v["motor.voltage"],
                    "speed": (r.columns["angle"][i1] - r.columns["angle"][i0]) / dt}

def test_gas_outputs_agree_with_the_pneumatics_api_and_a_full_pumpdown():
    cfg = load_config(EVP)
    p_mid, full = _full_pumpdown_window(cfg)
    s = study_from_dict({"study": {"config": EVP, "sampler": "grid", "booster_pressure": p_mid},
                         "vary": {"vane.mass": {"values": [0.00135]}}})
    assert {"gas_power", "pumping_speed", "mean_current"} <= set(s.outputs)  # all: with §8 tables
    df, _ = design.sweep(s, workers=0)
    row = df.iloc[0]
    assert row.status == "ok"
    # the same periodic steady state through the pneumatics package's own API
    m = pdm.pump_maps(cfg, [p_mid])
    assert row.speed == pytest.approx(m.speed[0], rel=ROUNDING_REL)
    assert row.gas_power == pytest.approx(m.gas_torque[0] * m.speed[0], rel=ROUNDING_REL)
    assert row.pumping_speed == pytest.approx(m.pumping_speed[0], rel=ROUNDING_REL)
    assert row.mean_current == pytest.approx(m.current[0], rel=ROUNDING_REL)
    # ... and against the full pump-down (`pumpsim pumpdown`'s model) at that booster pressure
    for k in ("pumping_speed", "gas_power", "speed"):
        assert row[k] == pytest.approx(full[k], rel=GAS_FLOW_VS_PUMPDOWN_REL), k
    assert row.mean_current == pytest.approx(full["mean_current"], rel=GAS_CURRENT_VS_PUMPDOWN_REL)
    # the friction is part of the shaft power the motor delivers (the gas power the rest)
    assert 0 < row.friction_power < row.mean_current * cfg.pneumatic.values["motor.voltage"]


def test_a_gas_config_is_studied_pumping_its_outputs_carry_the_gas_loads():
    """Spec §8: the drive torque includes the gas torque. Over a revolution of periodic steady
    state the shaft power is the friction power plus the gas power (the kinetic energy repeats);
    the study's mean torque meets that balance to the speed ripple's order, and the gas loads
    raise it above the mechanics alone by at least the gas torque (they press the vanes harder)."""
    pb = 60e3
    cfg = load_config(EVP)
    s = study_from_dict({"study": {"config": EVP, "sampler": "grid", "booster_pressure": pb},
                         "vary": {"vane.mass": {"values": [0.00135]}}})
    row = design.sweep(s, workers=0)[0].iloc[0]
    assert row.status == "ok"
    m = pdm.pump_maps(cfg, [pb])
    assert row.speed == pytest.approx(m.speed[0], rel=ROUNDING_REL)
    shaft = row.mean_torque * row.speed
    assert shaft == pytest.approx(row.friction_power + row.gas_power, rel=GAS_STUDY_BALANCE_REL)
    assert row.friction_power == pytest.approx(m.friction_torque[0] * m.speed[0], rel=GAS_STUDY_BALANCE_REL)
    # the same design with the mechanics alone, at the motor's speed
    mech = _mechanics_alone(s, {"vane.mass": 0.00135}, row.speed)
    assert row.mean_torque > mech["mean_torque"] + m.gas_torque[0]
    assert row.max_slot_force > mech["max_slot_force"]


def _mechanics_alone(study, values, speed):
    """The design's outputs from the mechanical kernel alone (no gas loads) at speed."""
    from pumpsim.design.evaluate import evaluate_designs, prepare, revolution
    from pumpsim.design.outputs import reduce_revolution
    from pumpsim.kernels import load_kernels

    pr = prepare(study, values)
    kern = load_kernels(pr.cfg.structure_for("constrained"))
    theta = revolution(pr.cfg.angle, study.revolution_samples)
    ev = evaluate_designs(kern, pr.p[None, :], theta[None, :], np.array([speed]))
    return reduce_revolution({k: v[0] for k, v in ev.items()}, pr.constants())[0]


def test_a_gas_config_refuses_the_contact_model_and_the_optimiser():
    with pytest.raises(Exception, match="study.model.*gas tables"):
        study_from_dict({"study": {"config": EVP, "model": "contact"}, "vary": {"vane.mass": {"values": [0.0012]}}})
    s = study_from_dict({"study": {"config": EVP}, "objective": {"minimize": "mean_torque"},
                         "vary": {"vane.mass": {"bounds": [0.001, 0.002], "distribution": "uniform",
                                                "low": 0.001, "high": 0.002}}})
    with pytest.raises(Exception, match="gas tables.*no kernel gradient"):
        design.optimize(s)

def test_gas_outputs_without_the_gas_tables_exit_2_naming_the_output(tmp_path, capsys):
    st = tmp_path / "s.toml"
    st.write_text(f'[study]\nconfig = "{RIG}"\noutputs = ["mean_torque", "pumping_speed"]\n'
                  '[vary."vane.mass"]\nvalues = [0.0012]\n')
    out = tmp_path / "res"
    assert main(["sweep", str(st), "--out", str(out), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "pumping_speed" in err and "[ports]" in err and "Traceback" not in err
    assert not out.exists()

def test_mean_current_needs_a_motor_and_speeds_contradict_one():
    speed_cfg = {"study": {"config": EVP, "outputs": ["gas_power", "mean_current"]},
                 "vary": {"vane.mass": {"values": [0.0012]}}}
    with pytest.raises(Exception, match="study.speeds"):
        study_from_dict({**speed_cfg, "study": {**speed_cfg["study"], "speeds": [400.0]}})
    s = study_from_dict(speed_cfg)
    assert s.booster_pressure == load_config(EVP).pneumatic.booster_start

def test_tip_pv_is_contact_pressure_times_slip_speed():
    """Concentric rig: N = m omega^2 r_G on every vane, slip speed omega R; PV = N / (w h) omega R,
    so doubling rotor.width halves it and leaves every force unchanged."""
    s = study_from_dict({"study": {"config": RIG, "sampler": "grid", "speeds": [607.37]},
                         "vary": {"rotor.width": {"values": [0.01, 0.02]}}})
    df, _ = design.sweep(s, workers=0)
    for r in df.itertuples():
        w = getattr(r, "_3")
        N = 0.0012 * r.speed**2 * (0.0225 - 0.006)
        assert r.max_tip_pv == pytest.approx(N / (w * 0.003) * r.speed * 0.0225, rel=CLOSED_FORM_REL)
    assert df.min_normal_force[0] == pytest.approx(df.min_normal_force[1], rel=ROUNDING_REL)

def test_tip_pv_without_rotor_width_is_refused_or_left_out(tmp_path):
    cfg = tmp_path / "rig.toml"
    cfg.write_text("\n".join(l for l in open(RIG).read().splitlines() if not l.startswith("width")))
    with pytest.raises(Exception, match="rotor.width"):
        study_from_dict({"study": {"config": str(cfg), "outputs": ["max_tip_pv"]},
                         "vary": {"vane.mass": {"values": [0.0012]}}})
    s = study_from_dict({"study": {"config": str(cfg)}, "vary": {"vane.mass": {"values": [0.0012]}}})
    assert "max_tip_pv" not in s.outputs and "mean_torque" in s.outputs


def test_optimiser_refuses_a_gas_objective():
    s = study_from_dict({"study": {"config": EVP}, "objective": {"minimize": "gas_power"},
                         "vary": {"vane.mass": {"bounds": [0.001, 0.002], "distribution": "uniform",
                                                "low": 0.001, "high": 0.002}}})
    with pytest.raises(Exception, match="gas_power.*no kernel gradient"):
        design.optimize(s)
