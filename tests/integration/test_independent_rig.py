"""Cross-check of pumpsim's constrained model against an independent implementation of spec §1-4
(bench/independent/rig.py: own derivation, numpy only, no pumpsim import), on six rig families;
plus the independent generator's own spec §4 closed forms, and the file formats it writes for the
diagnose benchmark read back by pumpsim."""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pumpsim
from tests.tolerances import (CLOSED_FORM_REL, INDEPENDENT_FORMAT_REL, INDEPENDENT_LOWPASS_REL, INDEPENDENT_MOTION_REL,
                              INDEPENDENT_PHASE_SHARE, INDEPENDENT_RIG_REL, POWER_BALANCE_REL, ZERO_MEAN_TORQUE_REL)

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.independent import artefacts  # noqa: E402
from bench.independent.formats import BAD_FORMATS, EXTRA_FORMATS, FORMATS, write  # noqa: E402
import bench.independent.records as records  # noqa: E402
from bench.independent.records import make_record  # noqa: E402
from bench.independent.rig import (RIGS, Friction, closed_form_concentric, drive_torque, friction_power,  # noqa: E402
                                   motion, to_toml, vane_kinematics)

RIG_DIR = ROOT / "bench" / "independent" / "rigs"


def _revolution(rig, n=720, theta0=0.0):
    t = np.arange(n) * (2 * np.pi / rig.speed) / n
    return t, *motion(t, rig.speed, theta0)


# the tilted 3-vane rig builds its own kernel variant (~50 s on a fresh machine): make test-all
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n == "tilted3" else n
                                  for n in sorted(RIGS)])
def test_pumpsim_matches_the_independent_model(name):
    """Torque and every vane's s, N, F1, F2 over a revolution agree to rounding."""
    rig = RIGS[name]
    res = pumpsim.simulate(pumpsim.load_config(RIG_DIR / f"{name}.toml"), duration=2 * np.pi / rig.speed,
                           rate=rig.speed / (2 * np.pi) * 360)
    t = np.asarray(res["time"])
    theta, omega, domega = motion(t, rig.speed)
    tau, vanes, paradox = drive_torque(rig, theta, omega, domega, details=True)
    scale = np.sqrt(np.mean(np.asarray(res["torque"]) ** 2))
    assert paradox == 0
    assert np.max(np.abs(tau - res["torque"])) <= INDEPENDENT_RIG_REL * scale
    for i, v in enumerate(vanes):
        force = np.max(np.abs(v["N"]))
        assert np.max(np.abs(v["s"] - res[f"s_{i}"])) <= INDEPENDENT_RIG_REL * rig.length
        for mine, theirs in (("N", "normal"), ("F1", "slot1"), ("F2", "slot2")):
            assert np.max(np.abs(v[mine] - res[f"{theirs}_{i}"])) <= INDEPENDENT_RIG_REL * force, (mine, i)


def test_rig_configs_are_the_generators():
    """The committed configs (built by make codegen) are exactly what the generator hands diagnose."""
    for name, rig in RIGS.items():
        assert (RIG_DIR / f"{name}.toml").read_text() == to_toml(rig)


def test_independent_closed_forms():
    """Spec §4 on the independent model: concentric torque, eccentric-circle stroke, power balance,
    zero mean torque without friction."""
    rig = RIGS["concentric4"]
    _, th, om, dom = _revolution(rig)
    assert np.allclose(drive_torque(rig, th, om, dom), closed_form_concentric(rig), rtol=CLOSED_FORM_REL, atol=0)
    ecc = replace(RIGS["eccentric5"], center=(0.002 * np.cos(0.7), 0.002 * np.sin(0.7)))
    _, th, om, dom = _revolution(ecc)
    e = 0.002
    for i in range(ecc.vanes):
        rel = th + 2 * np.pi * i / ecc.vanes - 0.7
        r = e * np.cos(rel) + np.sqrt(ecc.radius ** 2 - (e * np.sin(rel)) ** 2)
        s = vane_kinematics(ecc, i, th, om, dom)["s"]
        assert np.allclose(s, r - ecc.length - ecc.slot_radius, rtol=0, atol=CLOSED_FORM_REL * ecc.length)
    for rig in RIGS.values():
        _, th, om, dom = _revolution(rig, 2000)
        tau, vanes, _ = drive_torque(rig, th, om, dom, details=True)
        assert np.mean(tau * om) == pytest.approx(np.mean(friction_power(rig, vanes, om)), rel=POWER_BALANCE_REL)
        still = replace(rig, tip=Friction(0.0, 0.0), slot=Friction(0.0, 0.0))
        tau0 = drive_torque(still, th, om, dom)
        assert abs(np.mean(tau0)) <= ZERO_MEAN_TORQUE_REL * np.sqrt(np.mean(tau ** 2))


@pytest.mark.parametrize("fmt", FORMATS + EXTRA_FORMATS)
def test_every_written_format_reads_back(fmt, tmp_path):
    """Each rig-logger format the benchmark writes is read by pumpsim as the same SI torque (the
    extra ones: units in the header with reordered and extra columns; tab-separated decimal
    commas; comma-separated quoted decimal commas, which were refused: '4 values, the header has 3')."""
    rec = make_record("ellipse4", "none", 5.0, 3, rate=10000.0, duration=0.05)
    ds = pumpsim.load_data(write(rec, fmt, tmp_path / "data"))
    assert len(ds.torque) == len(rec.t)
    scale = np.sqrt(np.mean(rec.torque ** 2))
    assert np.max(np.abs(np.asarray(ds.torque) - rec.torque)) <= INDEPENDENT_FORMAT_REL * scale
    assert np.max(np.abs(np.asarray(ds.time) - rec.t)) <= INDEPENDENT_FORMAT_REL * rec.t[-1]


@pytest.mark.parametrize("fmt", BAD_FORMATS)
def test_unit_mistakes_in_a_written_file_are_refused_by_diagnose(fmt, tmp_path, capsys):
    """Time in ms or speed in rpm without a unit in the header: `pumpsim diagnose` exits 2 naming
    the column's likely unit and the fix, with nothing written and no traceback."""
    from pumpsim.cli import main

    rec = make_record("ellipse4", "none", 5.0, 3, rate=10000.0, duration=0.05)
    (tmp_path / "c.toml").write_text(to_toml(RIGS["ellipse4"]))
    js = tmp_path / "d.json"
    code = main(["diagnose", str(tmp_path / "c.toml"), write(rec, fmt, tmp_path / "data"), "--json", str(js)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and not js.exists()
    assert ("'time [ms]'" if fmt == "csv_ms_bare" else "'speed [rpm]'") in err, err


@pytest.mark.parametrize("kind", artefacts.ARTEFACTS)
def test_artefact_records_carry_their_artefact(kind):
    """Each artefact kind's record shows what it claims (and states its right answer)."""
    rec = make_record("ellipse3", kind, 5.0, 5, rate=10000.0, duration=0.2)
    p, t, y = rec.truth["params"], rec.t, rec.torque
    assert rec.truth["expected"] in ("quiet", "unexplained", "no_name") or isinstance(rec.truth["expected"], list)
    assert np.all(np.diff(t) > 0)
    dt = np.diff(t)
    if kind == "jitter":
        assert np.std(dt) > 0.05 / 10000.0
    elif kind == "dropped":
        assert len(t) < 2000 and rec.truth["samples_dropped"] == 2000 - len(t) and np.max(dt) > 1.5e-4
    else:
        assert len(t) == 2000 and np.ptp(dt) < 1e-9
    if kind == "quantised":
        steps = y / (p["lsb"] * rec.noise_rms)
        assert np.max(np.abs(steps - np.round(steps))) < 1e-6
    if kind == "clipped":
        assert np.sum(y == y.max()) >= 0.9 * p["fraction"] * len(y)
    if kind == "runup":
        assert rec.omega[0] < 0.96 * rec.omega[-1] and rec.omega[-1] == RIGS["ellipse3"].speed


def test_two_pump_effects_compose_as_one_config(tmp_path):
    """A moved housing centre and an extra lobe applied together by the generator are pumpsim's
    torque for the config that carries both (the combined record is one pump, not a sum of two)."""
    rig = RIGS["ellipse4"]
    comps = [("rotor_eccentricity", dict(e=1.1e-4, beta=2.2)), ("housing_out_of_round", dict(k=3, A=1.2e-5, gamma=0.4))]
    t = np.arange(360) * (2 * np.pi / rig.speed) / 360
    mine = records._shaft(rig, comps, 0.0, t[-1])(t)[0]
    moved = replace(rig, center=(float(1.1e-4 * np.cos(2.2)), float(1.1e-4 * np.sin(2.2))), harmonics=((3, 1.2e-5, 0.4),))
    (tmp_path / "pair.toml").write_text(to_toml(moved))
    res = pumpsim.simulate(pumpsim.load_config(tmp_path / "pair.toml"), duration=2 * np.pi / rig.speed,
                           rate=rig.speed / (2 * np.pi) * 360)
    theirs = np.asarray(res["torque"])[:t.size]
    assert np.max(np.abs(mine - theirs)) <= INDEPENDENT_RIG_REL * np.sqrt(np.mean(theirs ** 2))


def test_two_effects_record_carries_both():
    """A 'two_effects' record names both effects in its truth, each with its own observable share."""
    rec = make_record("ellipse4", "two_effects", 5.0, 11, rate=10000.0, duration=0.1)
    assert len(rec.truth["effects"]) == 2 and tuple(rec.truth["effects"]) in records.PAIRS
    assert set(rec.truth["observable"]) == set(rec.truth["effects"])


def test_ripple_and_drift_motion_is_consistent():
    """omega = d theta / dt and omega' = d omega / dt for the ripple + slow drift motion."""
    h = 1e-6
    t = np.linspace(0.0, 0.5, 101)
    args = (500.0, 0.3, (3, 0.01, 0.7), (0.008, 0.25, 0.5))
    th_p, om_p, _ = motion(t + h, *args)
    th_m, om_m, _ = motion(t - h, *args)
    _, om, dom = motion(t, *args)
    assert np.allclose((th_p - th_m) / (2 * h), om, rtol=INDEPENDENT_MOTION_REL, atol=0)
    assert np.allclose((om_p - om_m) / (2 * h), dom, rtol=0, atol=INDEPENDENT_MOTION_REL * np.max(np.abs(om)) / h)


def test_lowpass_sensor_converges(monkeypatch):
    """The generator's low-pass of the continuous torque (first-order hold on sub-steps) is converged:
    64 sub-steps per sample against 512."""
    rig = RIGS["ellipse3"]
    t = np.arange(1000) / 10000.0
    shaft = records._shaft(rig, [], 1.3, t[-1])
    T = 0.3 / (rig.vanes * rig.speed)
    y64 = records._lagged(shaft, "lowpass", T, t)
    monkeypatch.setattr(records, "LAG_OVERSAMPLING", 512)
    y512 = records._lagged(shaft, "lowpass", T, t)
    ripple = np.sqrt(np.mean((y512 - y512.mean()) ** 2))
    assert np.sqrt(np.mean((y64 - y512) ** 2)) <= INDEPENDENT_LOWPASS_REL * ripple


def test_turned_eccentric_housing_is_a_phase_shift():
    """The benchmark's observability check: an eccentric circle turned about the rotor axis is exactly a
    rotor phase shift (nothing to name), its centre moved radially is not."""
    rig = RIGS["eccentric5"]
    t = np.arange(2000) / 20000.0
    base = records._nominal(rig, t, 1.0)
    turned = replace(rig, center=(0.003 * np.cos(0.0237), 0.003 * np.sin(0.0237)))
    assert records.observable_share(rig, t, 1.0, records._nominal(turned, t, 1.0) - base) <= INDEPENDENT_PHASE_SHARE
    moved = replace(rig, center=(0.003 + 5e-5, 0.0))
    assert records.observable_share(rig, t, 1.0, records._nominal(moved, t, 1.0) - base) >= 0.1
