"""`pumpsim sensitivity` says when its sample is too small for the Sobol' indices it prints: the
text, the JSON (`unresolved`, `samples_needed`) and the HTML report carry the warning and the
--samples that would resolve them; a large sample of a function with known indices carries none."""
import json
import math

from pumpsim.cli import main
from pumpsim.design.analytic import ishigami_indices
from tests.conftest import EXAMPLES
from tests.tolerances import SOBOL_INTERVAL_FACTOR

STUDY = EXAMPLES / "studies" / "test_rig_tolerances.toml"


def _run(tmp_path, capsys, study, samples):
    out = tmp_path / f"s{samples}"
    rc = main(["sensitivity", str(study), "--samples", str(samples), "--workers", "1",
               "--json", f"{out}.json", "--report", f"{out}.html"])
    assert rc == 0
    text = capsys.readouterr().out
    return text, json.loads(out.with_suffix(".json").read_text()), out.with_suffix(".html").read_text()


def test_sixteen_samples_of_the_rig_study_are_flagged_everywhere(tmp_path, capsys):
    text, doc, page = _run(tmp_path, capsys, STUDY, 16)
    # measured: intervals up to +-0.6 on every output; the extensions' total indices sum to
    # 0.41 +- 0.25 although the keys explain all the variance
    assert doc["unresolved"] and {u["output"] for u in doc["unresolved"]} <= set(doc["indices"])
    need = doc["samples_needed"]
    assert need == max(u["samples_needed"] for u in doc["unresolved"]) and need > 16 and need & (need - 1) == 0
    worst = max(u["max_conf"] for u in doc["unresolved"])
    assert need >= 16 * (worst / 0.1) ** 2
    assert "WARNING: the sample (base N = 16, 112 designs) is too small" in text
    assert f"--samples {need} ({need * 7:,} designs" in text  # N (D + 2), D = 5 keys
    for u in doc["unresolved"]:
        assert u["output"] in text and u["reason"] in text
    assert "Sample too small" in page and f"--samples {need}" in page
    # before the figures, whose intervals are clipped to [0, 1]
    assert page.index("Sample too small") < page.index("<h2>Sobol")


def test_a_large_sample_of_ishigami_is_not_flagged_and_matches_the_closed_form(tmp_path, capsys):
    study = tmp_path / "ishigami.toml"
    study.write_text('[study]\nfunction = "ishigami"\nseed = 3\n' + "".join(
        f'[vary.{x}]\ndistribution = "uniform"\nlow = {-math.pi!r}\nhigh = {math.pi!r}\n' for x in ("x1", "x2", "x3")))
    text, doc, page = _run(tmp_path, capsys, study, 1024)
    assert doc["unresolved"] == [] and doc["samples_needed"] is None  # widest interval +-0.086
    assert "WARNING" not in text and "Sample too small" not in page
    for key, (s1, st) in ishigami_indices().items():
        got = doc["indices"]["y"][key]
        assert abs(got["S1"] - s1) <= SOBOL_INTERVAL_FACTOR * got["S1_conf"], key
        assert abs(got["ST"] - st) <= SOBOL_INTERVAL_FACTOR * got["ST_conf"], key
