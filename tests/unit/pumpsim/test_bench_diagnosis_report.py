"""The bench-log diagnosis page drawn from a hand-built BenchDiagnosis (the renderer's input, not a
diagnosis' output): a named effect, a confounded pair and an unexplained span each read as an
engineer needs them, in engineering units. The CLI path on a real log: test_bench_diagnose."""
import re

import numpy as np

from pumpsim.diagnosis.pump_effects import PUMP_EFFECTS
from pumpsim.diagnosis.pump_result import BenchDiagnosis, BenchModelFit, BenchStep
from pumpsim.diagnosis.pump_workflow import Confounded
from pumpsim.report.bench_diagnosis import bench_diagnosis_report

EFFECT = {e.name: e for e in PUMP_EFFECTS}


def result(steps, confounded=(), where=()):
    t = np.linspace(0.0, 0.5, 60)
    p = 101325 * np.exp(-2 * t)
    meas = {"booster_pressure": p, "current": 10 + 0 * t}
    hist = [BenchModelFit("baseline", 3.0, {"mu": {"value": 0.17, "stderr": 0.002}},
                          {"booster_pressure": p * 1.02, "current": 10.3 + 0 * t})]
    hist += [BenchModelFit(s.effect.name, s.rms_after, {}, meas) for s in steps]
    notes = tuple(Confounded(a, b, f"separate {a} from {b}", 0.999) for a, b in confounded)
    return BenchDiagnosis(
        baseline={"rms": 3.0, "params": hist[0].params}, steps=tuple(steps),
        final={"rms": steps[-1].rms_after if steps else 3.0, "params": {}, "residual_white": not where,
               "runs_p_value": 0.3, "ljung_box_p_value": 1e-30, "noise_level_p_value": 0.2},
        unexplained=bool(where), confounded=[list(c) for c in confounded], unexplained_where=list(where),
        verdict="a verdict", log=notes, detectors={}, ranking=[], method="m", wall_time=1.0, measured=meas,
        times={"booster_pressure": t, "current": t}, noise={"booster_pressure": 300.0, "current": 0.1},
        history=tuple(hist))


def test_named_effect_reads_with_its_interval_in_kpa_and_two_figures(tmp_path):
    step = BenchStep(EFFECT["valve_late"], {"valve.cracking": {"value": 12000.0, "stderr": 400.0}, "change": 10000.0},
                     3.0, 0.98, 1e-6, 30.0, 1e-9, 400.0, 10.0, 1.6)
    page = tmp_path / "r.html"
    bench_diagnosis_report(result([step]), page)
    html = page.read_text()
    assert "<b>valve_late</b>" in html and "12.00 ± 0.40" in html and "11.22 … 12.78" in html  # kPa, ± 1.96 s.e.
    assert "change +10 kPa" in html and "size 1.6 noise σ" in html
    assert "Ljung–Box &lt; 1e-16" in html or "Ljung–Box < 1e-16" in html
    assert len(re.findall(r"<img ", html)) == 2  # before/after; measured against baseline and final


def test_confounded_pair_names_its_experiment_and_unexplained_says_where(tmp_path):
    where = {"channel": "booster_pressure", "time": [0.2, 0.5], "pressure": [34740.0, 63270.0],
             "mean_residual": 1000.0, "unit": "Pa"}
    page = tmp_path / "r.html"
    bench_diagnosis_report(result([], [("booster_leak", "tip_clearance")], [where]), page)
    html = page.read_text()
    assert "Confounded: booster_leak ~ tip_clearance" in html and "separate booster_leak from tip_clearance" in html
    assert "in the booster pressure at t 0.2 … 0.5 s (booster pressure 34.74 … 63.27 kPa)" in html
    assert "mean residual +1 kPa" in html and "class=warn" in html
    assert len(re.findall(r"<img ", html)) == 1  # no before/after figure without a named effect


def test_effects_table_shows_the_final_models_figures_not_the_baselines(tmp_path):
    # a named motor friction refits the vane COF: the table must give the final model's, with the
    # effect's parameter as the final model holds it (a later step may refit it)
    step = BenchStep(EFFECT["motor_friction"], {"motor.friction": {"value": 0.031, "stderr": 0.001}, "change": 0.021},
                     3.0, 0.98, 1e-6, 30.0, 1e-9, 400.0, 10.0, 1.6)
    res = result([step])
    final = {"mu": {"value": 0.1432, "stderr": 0.0011}, "motor.friction": {"value": 0.0297, "stderr": 0.0009}}
    res = BenchDiagnosis(**{**res.__dict__, "final": {**res.final, "params": final}})
    page = tmp_path / "r.html"
    bench_diagnosis_report(res, page)
    table = page.read_text().split("<table")[1]  # the effects table comes first
    assert "final (with motor_friction)" in table
    assert "0.1432" in table and "0.1700" in table  # the final vane COF beside the baseline's
    assert "29.7" in table and "31.0" not in table  # mN m: the final friction, not the step's first fit
