"""A torque diagnosis whose reported fits (the baseline's, the final model's on the whole record)
did not converge -- here their Gauss-Newton held to a tenth of one step, which stops them at the
iteration limit far from the minimum: said in the notes, the JSON (baseline/final "converged"
false), the report and the command's exit status (1, the reason on stderr, the outputs written in
full), as the bench-log diagnosis does (test_bench_diagnose_not_converged). The same record
diagnosed as it is converges and exits 0: a healthy case is not flipped."""
import dataclasses
import html as _html
import json

import numpy as np
import pytest

from pumpsim.diagnosis import state
from pumpsim.diagnosis.result import DiagnosisResult
from tests.conftest import EXAMPLES, make_config
from tests.integration.test_diagnose_effects import measurement


@pytest.fixture(scope="module")
def ripple_record(tmp_path_factory):
    """A 1 % order-1 speed ripple on the 4-vane ellipse at effect RMS / noise = 5 (~0.6 s to
    diagnose): named by a fit that adds two parameters to the baseline's."""
    nominal = make_config("ellipse_4vanes")
    ds, _ = measurement(nominal, dataclasses.replace(nominal, angle=0.4, speed_ripple=(1, 0.01, 0.5)))
    path = tmp_path_factory.mktemp("ripple") / "d.csv"
    np.savetxt(path, np.column_stack([ds.time, ds.torque]), delimiter=",", header="time,torque", comments="")
    return path


def _hold_to_one_step(monkeypatch, only=None):
    """Every fit of the diagnosis (or those naming `only`) stopped after one Gauss-Newton step of a
    tenth of its length: the step left is ~0.9 of the way to the minimum, many standard errors (a
    whole step would leave a near-linear fit -- the baseline's -- within STEP_SE of it: converged)."""
    fit = state._identification_fit

    def held(cfg, data, params, *args, **kw):
        if only is None or only in params:
            kw["max_iter"], kw["relaxation"] = 1, 0.1
        return fit(cfg, data, params, *args, **kw)

    monkeypatch.setattr(state, "_identification_fit", held)


def _diagnose(tmp_path, data, *extra):
    from pumpsim.cli import main

    js, page = tmp_path / "d.json", tmp_path / "d.html"
    code = main(["diagnose", str(EXAMPLES / "ellipse_4vanes.toml"), str(data), "--json", str(js),
                 "--report", str(page), *extra])
    return code, json.loads(js.read_text()), _html.unescape(page.read_text())


def test_a_healthy_diagnosis_is_converged_and_exits_0(tmp_path, ripple_record, capsys):
    code, out, html = _diagnose(tmp_path, ripple_record)
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert out["effects"] == ["speed_ripple"]
    assert out["baseline"]["converged"] is True and out["final"]["converged"] is True
    assert "NOT converged" not in captured.out and "NOT converged" not in html and "provisional" not in out["verdict"]
    assert not any("NOT converged" in n for n in out["notes"])


def test_a_final_fit_that_did_not_converge_is_said_everywhere(tmp_path, ripple_record, monkeypatch, capsys):
    _hold_to_one_step(monkeypatch, only="ripple_cos")  # the effect's fits only: the baseline converges
    code, out, html = _diagnose(tmp_path, ripple_record)
    captured = capsys.readouterr()
    assert code == 1
    assert "not a usable estimate: the final model's fit is NOT converged" in captured.err
    assert "note: the final model's fit is NOT converged (maximum iterations reached; the remaining Gauss-Newton step is " in captured.out
    # the JSON in full: every key of a converged diagnosis, the flags false where the fit stopped
    assert set(out) == set(DiagnosisResult.JSON) and out["effects"] == ["speed_ripple"] and out["final"]["params"]
    assert set(out["final"]) >= {"rms", "params", "residual_white", "residual_tests_white", "converged"}
    assert out["baseline"]["converged"] is True and out["final"]["converged"] is False
    note = next(n for n in out["notes"] if n.startswith("the final model's fit is NOT converged"))
    assert "not the fit's minimum" in note and "diagnose again" in note
    assert "The final model's fit is NOT converged</b>: its figures are not the fit's minimum" in html
    # the verdict itself says so, not only the note above it
    assert out["verdict"].endswith("; provisional: the final fit did NOT converge")
    assert "<p class=ok>" not in html.split("<h2>")[0]  # no all-clear above the first section


def test_a_baseline_that_did_not_converge_is_said_everywhere(tmp_path, ripple_record, monkeypatch, capsys):
    _hold_to_one_step(monkeypatch)
    # a budget spent at once: the baseline only (it is the final model too)
    code, out, html = _diagnose(tmp_path, ripple_record, "--budget", "1e-6")
    captured = capsys.readouterr()
    assert code == 1
    assert "not a usable estimate: the baseline fit is NOT converged" in captured.err
    assert "final model" not in captured.err  # the final model is the baseline: said once
    assert "note: the baseline fit is NOT converged (maximum iterations reached; the remaining Gauss-Newton step is " in captured.out
    assert out["baseline"]["converged"] is False and out["final"]["converged"] is False
    assert out["steps"] == [] and out["final"]["params"]
    assert "The baseline fit is NOT converged</b>" in html
    assert out["verdict"].endswith("; provisional: the baseline fit did NOT converge")
