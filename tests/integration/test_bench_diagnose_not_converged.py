"""A bench-log diagnosis whose baseline fit does not converge (here its Gauss-Newton held to one
step; a start no step leaves that is not a minimum reads the same, test_bench_diagnosis_start):
said in the notes, the JSON (baseline and final "converged" false), the report's banner and the
command's exit status (1, with the reason on stderr), as identify's unusable fit. A fit that
converges says nothing of it (the CLI test of test_bench_diagnose: exit 0)."""
import json

from pumpsim.benchlog import write_bench_log
from pumpsim.config import load_config
from pumpsim.diagnosis import pump_workflow
from pumpsim.diagnosis.pump_twins import twin_with_fault
from tests.integration.test_bench_identify import small_booster


def test_a_baseline_that_did_not_converge_is_said_everywhere(tmp_path, monkeypatch, capsys):
    from pumpsim.cli import main

    cfg_path = small_booster(tmp_path)
    cfg = load_config(cfg_path)
    # vane COF 0.17 against the config's 0.15: one step does not settle the fit
    log = twin_with_fault(cfg, 0.2, 500, None, 0.0, values={"mu": 0.17}, noise=0.005, seed=3, rtol=1e-4, atol=1e-5)
    path = tmp_path / "bench.csv"
    write_bench_log(path, log)
    one_step = pump_workflow.gauss_newton
    monkeypatch.setattr(pump_workflow, "gauss_newton", lambda prob, x: one_step(prob, x, max_iter=1))
    js, page = tmp_path / "d.json", tmp_path / "d.html"
    # a budget spent at once: the baseline only
    code = main(["diagnose", str(cfg_path), str(path), "--json", str(js), "--report", str(page), "--budget", "1e-6"])
    captured = capsys.readouterr()
    assert code == 1
    assert "not a usable estimate: the baseline fit is NOT converged" in captured.err
    assert "note: the baseline fit is NOT converged (1 Gauss-Newton step did not settle" in captured.out
    out = json.loads(js.read_text())
    assert out["baseline"]["converged"] is False and out["final"]["converged"] is False
    assert any(n.startswith("the baseline fit is NOT converged") for n in out["notes"])
    assert out["verdict"] == "consistent with noise; provisional: the baseline fit did NOT converge"
    html = page.read_text()
    assert "<div class=warn>" in html and "The baseline fit is NOT converged</b>: the verdict may be wrong" in html
