"""Property tests (hypothesis): whatever config, data file or option set a user gives, the command
line ends with exit 0, 1 or 2, prints no traceback, and leaves no partial output.

- exit 2 (bad input): none of the requested outputs exists;
- exit 1 (numerical failure or unusable fit): an output is either absent or complete (parses);
- exit 0: every requested output exists;
- never a temporary file left beside the outputs.

Inputs are mutations of the bundled valid ones plus garbage. PUMPSIM_DEBUG=1 lets an unexpected
exception escape `main`, so a bug fails the test with its traceback instead of hiding behind the
catch-all. Runs are in-process and short (constrained model, a few ms simulated) so the examples
stay cheap; structures that would compile a new kernel (other vane counts, more harmonics) are
left out.
"""
import contextlib
import io
import json
import math
import os
import tempfile
import tomllib
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from pumpsim.cli import main  # noqa: E402
from tests.conftest import EXAMPLES, toml_text  # noqa: E402

RIG_TOML = (EXAMPLES / "test_rig.toml").read_text()
RIG_DICT = tomllib.loads(RIG_TOML)
RIG_CSV = (EXAMPLES / "data" / "test_rig_measurement.csv").read_text()

SETTINGS = settings(max_examples=25, deadline=None, database=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def run_cli(argv, outputs):
    """Run main(argv); check the exit status, stderr and the output files' state."""
    err, out = io.StringIO(), io.StringIO()
    old = os.environ.get("PUMPSIM_DEBUG")
    os.environ["PUMPSIM_DEBUG"] = "1"
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main([str(a) for a in argv])
    finally:
        if old is None:
            os.environ.pop("PUMPSIM_DEBUG")
        else:
            os.environ["PUMPSIM_DEBUG"] = old
    msg = err.getvalue()
    assert code in (0, 1, 2), (code, msg)
    assert "Traceback" not in msg
    if code != 0:
        assert "pumpsim: error" in msg or "pumpsim: the fit is not" in msg or "usage:" in msg, msg
    files = [Path(p) for p in outputs if p]
    if code == 2:
        assert not [f for f in files if f.is_file()], msg
    if code == 1:
        for f in files:
            if f.is_file() and f.suffix == ".json":
                json.loads(f.read_text())  # complete, not half-written
    if code == 0:
        assert all(f.is_file() for f in files), msg
    for f in files:
        folder = f.parent
        if folder.is_dir():
            assert not [p for p in folder.iterdir() if p.name.startswith(".") and ".tmp" in p.name]
    return code, msg


# --- configs --------------------------------------------------------------------------------

def _paths(d, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _paths(v, f"{prefix}{k}.")
        yield f"{prefix}{k}"


KEYS = sorted(set(_paths(RIG_DICT)) | {"housing.a", "housing.b", "housing.harmonics", "vane.inertia",
                                         "operation.mode", "operation.torque", "operation.speed_rpm",
                                         "friction.slot.static", "effects.speed_ripple",
                                         "effects.vane_friction_factors", "contact.housing.stiffness",
                                         "bogus", "housing.bogus"})
NUMBERS = st.one_of(st.sampled_from([0.0, -1.0, 1e-12, 1e12, math.inf, -math.inf, math.nan, 1000.0, 0.02]),
                    st.floats(allow_nan=True, allow_infinity=True, width=32))
VALUES = st.one_of(NUMBERS, st.integers(-3, 20).filter(lambda v: v in (0, -1, 17, 4, 20, -3)),
                   st.booleans(), st.text(max_size=8), st.just([]), st.just([1.0]),
                   st.just([[4, 1e-5, 0.0]]), st.just([1.0, 2.0, 3.0]), st.just({"x": 1}),
                   st.sampled_from(["speed", "torque", "circle", "ellipse", "impact"]), st.none())


def _set(d, path, value):
    node = d
    parts = path.split(".")
    for p in parts[:-1]:
        if not isinstance(node.get(p), dict):
            node[p] = {}
        node = node[p]
    if value is None:
        node.pop(parts[-1], None)
    else:
        node[parts[-1]] = value


@st.composite
def config_texts(draw):
    kind = draw(st.sampled_from(["mutated", "mutated", "mutated", "garbage", "truncated"]))
    if kind == "garbage":
        return draw(st.binary(max_size=200))
    if kind == "truncated":
        return RIG_TOML.encode()[:draw(st.integers(0, len(RIG_TOML)))]
    d = json.loads(json.dumps(RIG_DICT))
    for _ in range(draw(st.integers(1, 3))):
        _set(d, draw(st.sampled_from(KEYS)), draw(VALUES))
    text = toml_text(d)
    enc = draw(st.sampled_from(["utf-8", "utf-8-sig", "utf-16"]))
    return text.encode(enc)


@SETTINGS
@given(config_texts())
def test_any_config(content):
    with tempfile.TemporaryDirectory() as tmp:
        cfg, out = Path(tmp) / "c.toml", Path(tmp) / "o.csv"
        cfg.write_bytes(content)
        run_cli(["simulate", cfg, "--duration", "0.003", "--rate", "2000", "--out", out], [out])


# --- data files -----------------------------------------------------------------------------

HEADERS = ["time,torque,speed", "time [s],torque [N*mm],speed [rpm]", "time;torque;speed",
           "time [ms]\ttorque (mNm)\tspeed", "t,torque,speed", "time,torque [kgf],speed",
           "time,torque,torque", "time,torque", ",torque,speed", "time [s],torque [N*m],speed [rad/s]"]


@st.composite
def data_texts(draw):
    kind = draw(st.sampled_from(["mutated", "mutated", "mutated", "garbage", "header-only"]))
    if kind == "garbage":
        return draw(st.binary(max_size=300))
    lines = [ln for ln in RIG_CSV.splitlines() if ln and not ln.startswith("#")][:draw(st.integers(1, 1200))]
    header = draw(st.sampled_from(HEADERS))
    sep = ";" if ";" in header else ("\t" if "\t" in header else ",")
    if kind == "header-only":
        return (header + "\n").encode()
    rows = [ln.split(",") for ln in lines[1:]]
    scale = draw(st.sampled_from([1.0, 1000.0, 60 / (2 * math.pi), 1e-3]))
    col = draw(st.integers(0, 2))
    for r in rows:
        r[col] = repr(float(r[col]) * scale)
    for _ in range(draw(st.integers(0, 3))):
        if rows:
            i = draw(st.integers(0, len(rows) - 1))
            rows[i][draw(st.integers(0, 2))] = draw(st.sampled_from(["nan", "", "abc", "1e999", "-0", "1,5"]))
    if rows and draw(st.booleans()):
        i = draw(st.integers(0, len(rows) - 1))
        rows.insert(i, rows[0])  # a time going backwards
    if sep == ";":
        rows = [[x.replace(".", ",") for x in r] for r in rows]
    text = header + "\n" + "\n".join(sep.join(r) for r in rows) + "\n"
    bom = draw(st.sampled_from(["", "\ufeff"]))
    return (bom + text).encode(draw(st.sampled_from(["utf-8", "utf-16"])))


@SETTINGS
@given(data_texts(), st.sampled_from(["mu", "mu,theta0", "mu,speed", "mu,torque_offset"]))
def test_any_data_file(content, params):
    with tempfile.TemporaryDirectory() as tmp:
        data, js = Path(tmp) / "d.csv", Path(tmp) / "fit.json"
        data.write_bytes(content)
        run_cli(["identify", EXAMPLES / "test_rig.toml", data, "--params", params, "--max-iter", "5",
                 "--json", js], [js])


# --- option sets ----------------------------------------------------------------------------

NUMBER_TEXT = st.sampled_from(["0", "-1", "1e-4", "0.002", "nan", "inf", "abc", "1e9", "", "5000"])


@st.composite
def simulate_options(draw, tmp):
    argv, outputs = [], []
    for opt in ("--duration", "--rate", "--rtol", "--atol", "--max-step", "--max-steps"):
        if draw(st.booleans()):
            argv += [opt, draw(NUMBER_TEXT)]
    if "--duration" not in argv:
        argv += ["--duration", "0.002"]
    for opt, values in (("--method", ["cvodes", "idas", "rk", "euler"]),
                        ("--model", ["constrained", "contact", "magic"]),
                        ("--initial", ["bottom", "rotor", "housing", "air"])):
        if draw(st.booleans()):
            argv += [opt, draw(st.sampled_from(values))]
    names = ["o.csv", "o.png", "o.foo", "o.pdf", ".", "missing/o.csv", "o.svg", "c.toml"]
    for opt in ("--out", "--plot"):
        if draw(st.booleans()):
            p = str(tmp / draw(st.sampled_from(names)))
            argv += [opt, p]
            outputs.append(p)
    if draw(st.booleans()):
        argv.append(draw(st.sampled_from(["--keep-partial", "--force", "--bogus"])))
    return argv, outputs


@SETTINGS
@given(st.data())
def test_any_simulate_options(data):
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cfg = tmp / "c.toml"
        cfg.write_text(RIG_TOML)
        argv, outputs = data.draw(simulate_options(tmp))
        # the contact model needs a contact section: half the time give one
        if "contact" in argv and data.draw(st.booleans()):
            cfg.write_text(RIG_TOML + "\n[contact.housing]\nstiffness = 1e5\ndamping = 15.0\n")
        outputs = [o for o in outputs if not Path(o).is_dir() and Path(o) != cfg]
        run_cli(["simulate", cfg, *argv], outputs)
        assert cfg.read_text().startswith(RIG_TOML[:20])  # an input is never overwritten


@SETTINGS
@given(st.lists(st.sampled_from(["--params=mu", "--params=mu,bogus", "--params=,", "--params=mu,theta0,speed",
                                 "--method=ipopt", "--method=levenberg-marquardt", "--method=x",
                                 "--relaxation=0", "--relaxation=0.5", "--relaxation=nan",
                                 "--start=mu=0.05", "--start=mu", "--start=theta0=inf", "--max-iter=0",
                                 "--max-iter=2", "--torque-unit=N*mm", "--speed-unit=rpm",
                                 "--time-unit=ms", "--speed-unit=furlong", "--resample=5000",
                                 "--resample=-1", "--resample=1e12", "--steady", "--force",
                                 "--time-column=t", "--report=REPORT", "--json=REPORT"]),
                max_size=4))
def test_any_identify_options(options):
    with tempfile.TemporaryDirectory() as tmp:
        js, rep = Path(tmp) / "fit.json", Path(tmp) / "fit.html"
        argv = ["--json", str(js)] + [o.replace("REPORT", str(rep)) for o in options]
        given = {}
        for o in argv[2:]:
            if o.startswith(("--json=", "--report=")):
                given[o.split("=", 1)[0]] = o.split("=", 1)[1]
        outputs = [given.get("--json", js)] + ([given["--report"]] if "--report" in given else [])
        run_cli(["identify", EXAMPLES / "test_rig.toml", EXAMPLES / "data" / "test_rig_measurement.csv",
                 *argv], outputs)
