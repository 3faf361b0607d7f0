"""Spec §5: every rejection rule names the key and the limit; the CLI exits 2 and writes nothing."""
import math
import subprocess
import sys

import pytest

from pumpsim.config import config_from_dict, load_config
from pumpsim.errors import ConfigError
from pumpsim.geometry import check_geometry
from tests.conftest import ROOT, apply_changes, example_dict
from tests.tolerances import ROUNDING_REL

REJECTIONS = [
    # (changes, message fragment)
    ({"housing.colour": "red"}, "unknown key 'housing.colour'"),
    ({"rotor.vanez": 3}, "did you mean 'rotor.vanes'"),
    ({"rotor.radius": None}, "missing required key 'rotor.radius'"),
    ({"friction.housing.dynamic": None}, "missing required key 'friction.housing.dynamic'"),
    ({"rotor.vanes": 2.5}, "'rotor.vanes' must be an integer"),
    ({"vane.mass": "heavy"}, "'vane.mass' must be a number"),
    ({"vane.mass": 0.0}, "vane.mass must be > 0, got 0"),
    ({"vane.length": -0.01}, "vane.length must be > 0"),
    ({"rotor.inertia": -1.0}, "rotor.inertia must be > 0"),
    ({"vane.thickness": 0.0}, "vane.thickness must be > 0"),
    ({"rotor.vanes": 0}, "rotor.vanes must be >= 1"),
    ({"housing.radius": 0.019}, "housing.radius must be > rotor.radius (0.0200 m), got 0.0190"),
    ({"friction.housing.dynamic": 2.5}, "friction.housing.dynamic must be in [0, 2], got 2.5"),
    ({"friction.housing.static": -0.1}, "friction.housing.static must be in [0, 2]"),
    ({"operation.speed_tolerance": 0.7}, "operation.speed_tolerance must be in [0, 0.5], got 0.7"),
    ({"friction.slot.static": 0.2, "friction.slot.dynamic": 3.0, "friction.slot.v_static": 1e-4,
      "friction.slot.v_dynamic": 1e-3}, "friction.slot.dynamic must be in [0, 2], got 3"),
    ({"friction.housing.v_static": 2e-3}, "friction.housing.v_static must be < friction.housing.v_dynamic"),
    ({"housing.shape": "square"}, "housing.shape must be \"circle\" or \"ellipse\""),
    ({"housing.shape": "ellipse"}, "housing.radius is for shape = \"ellipse\"".replace("ellipse\"", "circle\"")),
    ({"contact.housing.law": "rubber"}, "contact.housing.law must be one of linear, hunt-crossley, impact"),
    ({"contact.housing.stiffness": -5.0}, "contact.housing.stiffness must be > 0"),
    ({"operation.mode": "walk"}, "operation.mode must be \"speed\" or \"torque\""),
    ({"operation.speed_rpm": None}, "missing required key 'operation.speed'"),
    ({"operation.speed": 600.0}, "give operation.speed (rad/s) or operation.speed_rpm, not both"),
    ({"operation.mode": "torque"}, "missing required key 'operation.torque'"),
    ({"rotor.slot_radius": 0.021}, "rotor.slot_radius must be in [0, rotor.radius (0.0200 m))"),
    ({"rotor.slot_tilt": 2.0}, "rotor.slot_tilt must be in (-pi/2, pi/2)"),
    ({"vane.tip_radius": 0.007}, "vane.tip_radius must be in [0, vane.length/2"),
    ({"housing.harmonics": [[2.5, 1e-5, 0.0]]}, "housing.harmonics[0]: order k must be an integer >= 1"),
    ({"housing.harmonics": [[2, 1e-5]]}, "housing.harmonics[0] must be [order k, amplitude A_k, phase gamma_k]"),
    ({"housing.center": [0.0]}, "housing.center must be a list of two numbers"),
    ({"effects.vane_friction_factors": [1.0, 1.0]}, "effects.vane_friction_factors must be 4 numbers"),
]

GEOMETRY = [
    ({"housing.center": [0.003, 0.0]}, "rotor circle (rotor.radius 0.0200 m) must lie strictly inside"),
    ({"vane.length": 0.014}, "vane.length 0.0140 m is too long"),
    ({"vane.length": 0.0005, "rotor.slot_radius": 0.0}, "vane.length 0.0005 m is too short"),
    ({"housing.harmonics": [[8, 0.0015, 0.0]]}, "housing is not convex"),
]


@pytest.mark.parametrize("changes,message", REJECTIONS)
def test_value_rejections_name_the_key(changes, message):
    with pytest.raises(ConfigError) as e:
        config_from_dict(apply_changes(example_dict(), changes))
    assert message in str(e.value)


@pytest.mark.parametrize("changes,message", GEOMETRY)
def test_geometry_rejections_name_the_condition(changes, message):
    with pytest.raises(ConfigError) as e:
        check_geometry(config_from_dict(apply_changes(example_dict(), changes)))
    assert message in str(e.value)
    if "rad" in message or "too" in message:
        assert "angle" in str(e.value)


def test_defaults_and_rpm():
    cfg = config_from_dict(example_dict())
    assert cfg.speed == pytest.approx(5800 * 2 * math.pi / 60, rel=ROUNDING_REL)
    v = cfg.values
    assert v["vane.inertia"] == pytest.approx(0.0012 * (0.012**2 + 0.003**2) / 12, rel=ROUNDING_REL)
    assert v["friction.slot.dynamic"] == v["friction.housing.dynamic"]


def test_bad_toml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[housing\nshape=1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)
    with pytest.raises(ConfigError, match="cannot read config"):
        load_config(tmp_path / "none.toml")


def _write_toml(path, d):
    lines = []

    def emit(prefix, table):
        scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
        if prefix:
            lines.append(f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f"{k} = {_toml(v)}")
        for k, v in table.items():
            if isinstance(v, dict):
                emit(f"{prefix}.{k}" if prefix else k, v)

    emit("", d)
    path.write_text("\n".join(lines) + "\n")


def _toml(v):
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(v)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pumpsim", *args], capture_output=True, text=True,
                          cwd=ROOT)


@pytest.mark.parametrize("changes,message", [REJECTIONS[11], GEOMETRY[1]])
def test_cli_rejects_bad_config_with_status_2_and_writes_nothing(tmp_path, changes, message):
    cfg = tmp_path / "c.toml"
    _write_toml(cfg, apply_changes(example_dict(), changes))
    out, png = tmp_path / "o.csv", tmp_path / "o.png"
    r = _cli("simulate", str(cfg), "--out", str(out), "--plot", str(png))
    assert r.returncode == 2
    assert message in r.stderr and "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == [cfg]


@pytest.mark.parametrize("args,message", [
    (["--duration", "-1"], "duration must be > 0"),
    (["--rate", "0"], "rate must be > 0"),
    (["--model", "magic"], "invalid choice: 'magic'"),
    (["--out", "/nonexistent/dir/o.csv"], "output folder '/nonexistent/dir' does not exist"),
])
def test_cli_rejects_bad_options(tmp_path, args, message):
    r = _cli("simulate", str(ROOT / "examples" / "test_rig.toml"), *args)
    assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr
