"""Identification results are built by keyword and say what they came from."""
import hashlib

import pytest

from pumpsim.data import load_data
from pumpsim.identification import FitOutcome, IdentificationResult, gauss_newton, identify, make_problem
from pumpsim.kernels import load_kernels
from tests.conftest import ROOT, make_config


def test_result_names_config_data_file_hash_and_kernel():
    cfg = make_config()
    path = ROOT / "examples" / "data" / "test_rig_measurement.csv"
    data = load_data(path)
    res = identify(cfg, data.window(0, 2000), params=["mu"])
    pv = res.provenance
    assert pv["data"] == [{"name": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}]
    assert pv["kernel_key"] == load_kernels(cfg.parameters().structure).key
    assert pv["config"] == cfg.name and res.to_json()["provenance"] == pv
    text = str(res)
    assert path.name in text and pv["kernel_key"] in text and "mu" in text


def test_result_is_built_by_keyword_and_optimisers_name_their_outcome():
    with pytest.raises(TypeError):
        IdentificationResult({}, [], 0.0, True, "", None, {}, "gauss-newton", 0.0)
    cfg = make_config()
    data = load_data(ROOT / "examples" / "data" / "test_rig_measurement.csv").window(0, 1000)
    prob = make_problem(cfg, data, ["mu"])
    out = gauss_newton(prob, prob.x0)
    assert isinstance(out, FitOutcome) and out.converged and 0.0 < out.x[0] < 2.0 and out.history
    x, r, J, history, converged, message = out  # still unpacks
    assert J.shape == (1000, 1) and r is out.residual
