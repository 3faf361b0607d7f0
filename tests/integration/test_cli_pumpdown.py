"""Pump-down (spec §8): fast path vs full model, and the command's contract."""
import json
import math
import shutil

import numpy as np
import pytest

from pumpsim.cli import main
from pumpsim.pneumatics import pumpdown as pdm
from tests.conftest import EXAMPLES
from tests.pneumatic_helpers import evp_config
from pumpsim.tolerances import PUMPDOWN_ATOL, PUMPDOWN_RTOL
from tests.tolerances import FAST_PATH_REL, PUMPDOWN_CONVERGED_REL, ROUNDING_REL, TARGET_LOCATED_REL

EVP = str(EXAMPLES / "evp_booster.toml")


def test_fast_path_agrees_with_the_full_model():
    """A 1 L booster from 101.3 to 30 kPa: time to target and mean current within 2 %."""
    cfg = evp_config(**{"booster.volume": 1.0e-3})
    full = pdm.pumpdown(cfg)
    assert full.summary["time_to_target"] is not None
    maps = pdm.pump_maps(cfg, np.geomspace(25e3, cfg.pneumatic.booster_start, 8))
    fast = pdm.fast_pumpdown(cfg, maps)
    assert fast["time_to_target"] == pytest.approx(full.summary["time_to_target"], rel=FAST_PATH_REL)
    assert fast["mean_current"] == pytest.approx(full.summary["mean_current"], rel=FAST_PATH_REL)
    # the maps are physical: less flow and more current as the booster empties
    assert np.all(np.diff(maps.mass_flow) > 0) and maps.current[0] > maps.current[-1]


def test_fast_path_short_of_the_target_covers_the_same_time(tmp_path, capsys):
    """--fast with a --duration that stops short of the target: the fast path runs over the same
    time, so its final pressure and mean current compare with the full run's (before: twice the
    time, and only 'target not reached' printed)."""
    js = tmp_path / "pd.json"
    assert main(["pumpdown", EVP, "--duration", "0.4", "--fast", "--json", str(js)]) == 0
    s = json.loads(js.read_text())
    fast = s["fast_path"]
    assert s["time_to_target"] is None and fast["time"][-1] == pytest.approx(s["duration"], rel=ROUNDING_REL)
    assert fast["final_pressure"] == pytest.approx(s["final_pressure"], rel=FAST_PATH_REL)
    assert fast["mean_current"] == pytest.approx(s["mean_current"], rel=FAST_PATH_REL)
    assert f"booster {fast['final_pressure'] / 1e3:.2f} kPa at" in capsys.readouterr().out


def test_default_tolerances_are_converged():
    """A 1 L booster from 101.3 to 30 kPa at the default tolerances and 100x tighter: time to
    target, mean current and the booster pressure curve agree within PUMPDOWN_CONVERGED_REL."""
    cfg = evp_config(**{"booster.volume": 1.0e-3})
    default = pdm.pumpdown(cfg)
    assert (default.summary["solver"]["rtol"], default.summary["solver"]["atol"]) == (PUMPDOWN_RTOL, PUMPDOWN_ATOL)
    tight = pdm.pumpdown(cfg, rtol=PUMPDOWN_RTOL / 100, atol=PUMPDOWN_ATOL / 100)
    for k in ("time_to_target", "mean_current"):
        assert default.summary[k] == pytest.approx(tight.summary[k], rel=PUMPDOWN_CONVERGED_REL), k
    n = min(len(default.time), len(tight.time)) - 1  # the same output grid up to the target
    np.testing.assert_allclose(default.columns["booster_pressure"][:n], tight.columns["booster_pressure"][:n],
                               rtol=PUMPDOWN_CONVERGED_REL)


def test_pumpdown_command_writes_the_spec_columns_and_json(tmp_path):
    out, js = tmp_path / "pd.csv", tmp_path / "pd.json"
    assert main(["pumpdown", EVP, "--duration", "0.03", "--out", str(out), "--json", str(js)]) == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header[:6] == ["time", "angle", "speed", "torque", "booster_pressure", "current"]
    for i in range(4):
        assert {f"pressure_{i}", f"volume_{i}", f"temperature_{i}"} <= set(header)
    s = json.loads(js.read_text())
    for k in ("time_to_target", "final_pressure", "energy", "peak_current", "mean_current", "solver"):
        assert k in s
    assert s["time_to_target"] is None and s["final_pressure"] < 101300.0
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data[-1, 0] == pytest.approx(0.03, rel=ROUNDING_REL)
    assert s["energy"] > 0 and s["peak_current"] > s["mean_current"] > 0


@pytest.mark.parametrize("args,message", [
    (["--until", "2e5"], "until must be in (0, booster.pressure"),
    (["--out", "/nonexistent/x.csv"], "output folder '/nonexistent' does not exist"),
    (["--plot", "x.svg"], "--plot 'x.svg': the file type must be one of .png"),
    (["--duration", "-1"], "duration must be > 0"),
])
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, args, message):
    js = tmp_path / "pd.json"
    assert main(["pumpdown", EVP, "--json", str(js), *args]) == 2
    assert message in capsys.readouterr().err
    assert not js.exists()


@pytest.mark.parametrize("extra,message", [
    (["--out", "{config}"], "is an input file of this run"),  # before: the CSV replaced the config
    (["--out", "{d}/same.json", "--json", "{d}/same.json"], "name the same file"),
    (["--out", "{d}"], "is a folder"),
    (["--report", "{d}/r.txt"], "the file type must be one of .htm, .html"),
    (["--json", "/proc/pd.json"], "cannot create a file in folder '/proc'"),
])
def test_output_paths_are_checked_before_the_pumpdown(tmp_path, capsys, extra, message):
    """Every output path is refused before any work (no summary printed) and nothing is written;
    the config named as an output is left as it was."""
    config = tmp_path / "evp.toml"
    shutil.copy(EVP, config)
    text = config.read_text()
    args = [a.replace("{d}", str(tmp_path)).replace("{config}", str(config)) for a in extra]
    before = set(tmp_path.iterdir())
    assert main(["pumpdown", str(config), "--duration", "0.005", *args]) == 2
    out, err = capsys.readouterr()
    assert message in err and "pump-down of" not in out, err
    assert set(tmp_path.iterdir()) == before and config.read_text() == text


def test_torque_drive_is_refused(tmp_path, capsys):
    """The gas model runs at constant speed or with the motor (before: a pump-down at rest, exit 0)."""
    cfg = tmp_path / "torque.toml"
    cfg.write_text(open(EVP).read().replace('mode = "motor"', 'mode = "torque"\ntorque = 0.2'))
    js = tmp_path / "pd.json"
    assert main(["pumpdown", str(cfg), "--duration", "0.005", "--json", str(js)]) == 2
    assert 'operation.mode = "torque"' in capsys.readouterr().err and not js.exists()


def test_unit_mistake_is_refused_and_force_proceeds(tmp_path, capsys):
    """The config's unit/plausibility checks as in simulate: refused naming the key, --force runs
    with the warning (before: no --force, the refusal could not be overridden)."""
    cfg = tmp_path / "grams.toml"
    cfg.write_text(open(EVP).read().replace("mass = 0.00135", "mass = 1.35"))  # grams typed as kg
    js = tmp_path / "pd.json"
    assert main(["pumpdown", str(cfg), "--duration", "0.002", "--json", str(js)]) == 2
    err = capsys.readouterr().err
    assert "vane.mass" in err and "force option" in err and not js.exists()
    assert main(["pumpdown", str(cfg), "--duration", "0.002", "--json", str(js), "--force"]) == 0
    assert "warning: vane.mass" in capsys.readouterr().err and js.exists()


@pytest.mark.parametrize("old,new,key", [
    ("volume = 4.0e-3", "volume = 4.0", "booster.volume = 4 m^3"),  # litres typed as m^3
    ("pressure = 101300.0\ntarget = 30000.0", "pressure = 101.3\ntarget = 30.0",
     "gas.atmosphere = 101.325 Pa"),  # every pressure in kPa
])
def test_gas_unit_mistakes_are_refused(tmp_path, capsys, old, new, key):
    cfg = tmp_path / "units.toml"
    text = open(EVP).read().replace(old, new, 1)
    if "101.3\n" in new:
        text = text.replace("[gas]", "[gas]\natmosphere = 101.325", 1)
    cfg.write_text(text)
    js = tmp_path / "pd.json"
    assert main(["pumpdown", str(cfg), "--duration", "0.002", "--json", str(js)]) == 2
    err = capsys.readouterr().err
    assert key in err and "SI" in err and "force option" in err and not js.exists(), err


def test_mechanical_config_is_rejected(capsys):
    assert main(["pumpdown", str(EXAMPLES / "ellipse_4vanes.toml")]) == 2
    assert "needs the gas tables" in capsys.readouterr().err


def test_time_to_target_is_located_exactly():
    cfg = evp_config(**{"booster.volume": 2.0e-4, "booster.target": 90000.0})
    r = pdm.pumpdown(cfg, rate=500.0)
    assert r.summary["final_pressure"] == pytest.approx(90000.0, rel=TARGET_LOCATED_REL)
    assert math.isclose(r.time[-1], r.summary["time_to_target"])
