"""`pumpsim identify CONFIG LOG --report X.html [--limits FILE.toml]` on a bench log: the page holds
the verdict, the identified figures against their limits, the measured-against-fitted panels and the
provenance; bad limits are refused before any fit."""
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from pumpsim.benchlog import write_bench_log
from pumpsim.config import load_config
from pumpsim.identification.pumpdown_fit import twin_log
from pumpsim.identification.result import Estimate
from pumpsim.presentation import fmt_estimate
from pumpsim.report.benchlog import channel_figure, effects_figure, figures_table
from tests.conftest import ROOT
from tests.integration.test_bench_identify import small_booster

TRUE_MU = 0.165


def identify(*args):
    return subprocess.run([sys.executable, "-m", "pumpsim", "identify", *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT)


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """A 0.2 s twin log with speed, its config and a limits file whose upper mu the truth exceeds."""
    tmp = tmp_path_factory.mktemp("bench_report")
    cfg_path = small_booster(tmp)
    log = twin_log(load_config(cfg_path), 0.2, 1000, values={"mu": TRUE_MU}, noise=0.005, seed=4, speed=True)
    write_bench_log(tmp / "bench.csv", log)
    (tmp / "limits.toml").write_text("[limits.mu]\nlower = 0.10\nupper = 0.16\n")
    return tmp, cfg_path


def test_report_shows_figures_limits_panels_and_provenance(bench):
    tmp, cfg_path = bench
    page, js = tmp / "fit.html", tmp / "fit.json"
    r = identify(cfg_path, tmp / "bench.csv", "--params", "mu", "--limits", tmp / "limits.toml",
                 "--report", page, "--json", js)
    assert r.returncode == 0, r.stderr  # a pump out of specification is a result, not a failure
    out = json.loads(js.read_text())
    mu = out["params"]["mu"]
    # the fit recovers mu (0.5 % noise), so 0.165 > 0.16 is out: this 0.2 s log gives 0.1723, 4.0
    # standard errors (4.4 %) high with either CVODES driver, a bias the covariance does not hold
    # (the start pressure's estimate is its main known source, docs/explanation/bench-log.md)
    assert abs(mu["value"] - TRUE_MU) < max(4 * mu["stderr"], 0.05 * TRUE_MU), mu
    assert out["limits"]["mu"] == {"lower": 0.10, "upper": 0.16, "status": "out of specification"}
    assert "specification: mu out of specification" in r.stdout
    text = page.read_text()
    assert text.count("<img") == 1  # the channel panels: pressure, current, speed with residuals
    assert "Usable estimate" in text and "Out of specification: mu" in text
    assert f"mu {mu['value']:.4g} &gt; upper limit 0.16" in text
    assert fmt_estimate(mu["value"], mu["stderr"]) in text  # the estimate as the terminal rounds it
    assert re.search(r"<tr class=out><td class=t>mu</td>", text)
    for channel in ("booster pressure", "motor current", "rotor speed"):  # the fit-per-channel rows
        assert f"<td class=t>{channel}</td>" in text
    assert "limits file SHA-256" in text and "data file SHA-256" in text and "compiled kernel" in text


@pytest.mark.parametrize("text, words", [
    ('[limits."motor.constant"]\nupper = 0.02\n', ['limits."motor.constant" is not a fitted parameter']),
    ("[limits.mu]\nlower = 0.2\nupper = 0.1\n", ["limits.mu.lower (0.2) must be < upper (0.1)"]),
])
def test_bad_limits_exit_2_before_the_fit(bench, tmp_path, text, words):
    _, cfg_path = bench
    lim = tmp_path / "bad.toml"
    lim.write_text(text)
    r = identify(cfg_path, bench[0] / "bench.csv", "--params", "mu", "--limits", lim)
    assert r.returncode == 2, r.stderr
    assert all(w in r.stderr for w in words) and "--limits" in r.stderr and "Traceback" not in r.stderr
    assert "residual RMS" not in r.stdout  # refused before the fit


def test_limits_on_torque_data_are_refused(tmp_path):
    from tests.conftest import EXAMPLES

    lim = tmp_path / "lim.toml"
    lim.write_text("[limits.mu]\nupper = 0.2\n")
    r = identify(EXAMPLES / "test_rig.toml", EXAMPLES / "data" / "test_rig_measurement.csv", "--limits", lim)
    assert r.returncode == 2 and "--limits" in r.stderr and "bench log" in r.stderr, r.stderr


def test_figures_table_flags_each_status():
    est = {"mu": Estimate("mu", 0.17, 0.001, 0.168, 0.172, 0.15),
           "booster.leak": Estimate("booster.leak", 2.7e-5, 1e-6, 2.5e-5, 2.9e-5, 5e-7),
           "motor.resistance": Estimate("motor.resistance", 0.271, 0.0007, 0.2696, 0.2724, 0.25),
           "leak.tip_gap": Estimate("leak.tip_gap", None, None, None, None, 1e-5, identifiable=False)}
    lim = {"mu": (0.12, 0.2), "booster.leak": (None, 2.5e-5), "motor.resistance": (0.2, 0.2715),
           "leak.tip_gap": (None, 2e-5)}
    text = figures_table(est, {"mu": 0.15}, lim)
    rows = {m.group(1): m.group(0) for m in re.finditer(r"<tr[^>]*><td class=t>([\w.]+)</td>.*?</tr>", text)}
    assert "in specification" in rows["mu"] and "class=out" not in rows["mu"]
    assert "<b>out of specification</b>" in rows["booster.leak"] and "class=out" in rows["booster.leak"]
    assert "mg/s" in rows["booster.leak"] and ">25<" in rows["booster.leak"]  # the limit in the row's unit
    assert "undecided" in rows["motor.resistance"] and "undecided</i>: the estimate" in text
    assert "not identifiable from this log" in rows["leak.tip_gap"] and "not checked" in rows["leak.tip_gap"]
    assert "µm" in rows["leak.tip_gap"] and ">20<" in rows["leak.tip_gap"]
    judged = figures_table(est, {}, lim, judged=False)
    assert "out of specification" not in judged and judged.count("not judged") == 4


def test_diagnosis_pieces_draw_two_models_and_named_effects():
    """What a bench-log diagnosis page draws: the nominal and the refitted model over the log, and
    each named effect's residual before and after."""
    t = np.linspace(0, 0.3, 301)
    p = 101325 * np.exp(-10 * t)  # a pump-down over more than a decade: the log axis
    measured = {"booster_pressure": p + 50 * np.sin(40 * t)}
    models = {"nominal model": {"booster_pressure": p * 1.05}, "refitted": {"booster_pressure": p}}
    html = channel_figure({"booster_pressure": t}, measured, models, {"booster_pressure": 40.0})
    assert html.startswith('<img alt="figure" src="data:image/png;base64,') and len(html) > 10000
    bars = effects_figure([("booster_leak", 12.0, 1.1), ("tip_clearance", 12.0, 9.5)])
    assert bars.startswith("<img") and len(bars) > 5000
