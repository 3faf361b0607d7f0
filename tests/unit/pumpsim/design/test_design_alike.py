"""Alike vanes through one vane (design/alike.py) and the batch geometry screen (design/screen.py):
the one-vane library is the N-vane library's vane body, one vane's shifted samples stand for every
vane within the kernel's rounding, and study rows match the every-vane evaluation's."""
import dataclasses
import math

import numpy as np
import pytest

from pumpsim.design import alike, evaluate, screen
from pumpsim.design.evaluate import evaluate_designs, housing_check_samples, revolution
from pumpsim.design.study import study_from_dict
from pumpsim.model_spec.parameters import layout_names
from tests.conftest import EXAMPLES, kernel_and_p, make_config
from tests.tolerances import SIMD_REL


def _designs(vanes=4, n=360):
    """Four ellipse designs (semi-axes, COF, start angle, speed), with `vanes` vanes."""
    cfgs = [make_config("test_rig", **{"housing.radius": None, "housing.shape": "ellipse", "rotor.vanes": vanes,
                                       "housing.a": 0.0225 + 2e-4 * k, "housing.b": 0.0225 - 1e-4 * k,
                                       "friction.housing.dynamic": 0.1 + 0.03 * k, "operation.angle": 0.1 * k})
            for k in range(4)]
    kern = kernel_and_p(cfgs[0])[0]
    P = np.array([kernel_and_p(c)[1] for c in cfgs])
    theta = np.array([revolution(c.angle, n) for c in cfgs])
    return kern, P, theta, np.array([300.0, 410.0, 520.0, 630.0])


@pytest.fixture(scope="module")
def four():
    kern, P, theta, omega = _designs()
    one = evaluate.one_vane(kern.structure)
    if one is None:
        pytest.skip("no SIMD library on this machine")
    return kern, P, theta, omega, one


def test_the_one_vane_library_is_vane_zero_bit_for_bit(four):
    kern, P, theta, omega, one = four
    full = evaluate_designs(kern, P, theta, omega)
    mine = one.evaluate(P, theta, omega, evaluate.KERNEL_OUTPUTS)
    for nm, a in mine.items():
        if nm != "torque":
            assert np.array_equal(a[:, 0], full[nm][:, 0], equal_nan=True), nm


@pytest.mark.parametrize("vanes", [3, 4, 6])
def test_one_vane_stands_for_every_vane_within_the_kernels_rounding(vanes):
    kern, P, theta, omega = _designs(vanes)
    one = evaluate.one_vane(kern.structure)
    if one is None:
        pytest.skip("no SIMD library on this machine")
    assert one.alike(P, 360).all()
    full = evaluate_designs(kern, P, theta, omega)
    mine = alike.spread(one.evaluate(P, theta, omega, evaluate.KERNEL_OUTPUTS), vanes, 360)
    for nm, a in mine.items():
        assert a.shape == full[nm].shape, nm
        b = full[nm]
        if nm == "position_residual":  # rounding noise in both: in units of the housing's size
            assert np.abs(a - b).max() <= SIMD_REL * 0.0225, nm
        elif nm in ("n_consistent", "ambiguity"):
            assert np.array_equal(a, b), nm
        else:
            assert np.abs(a - b).max() <= SIMD_REL * np.abs(b).max(), nm


def test_unlike_vanes_or_a_revolution_they_do_not_divide_get_every_vane(four):
    kern, P, theta, omega, one = four
    Q = P.copy()
    Q[1, one.factors[2]] = 0.9  # vane 2 of design 1 rubs less
    assert one.alike(Q, 360).tolist() == [True, False, True, True]
    assert not one.alike(P, 361).any()
    evs = evaluate.revolutions(kern, Q, theta, omega)
    full = evaluate_designs(kern, Q[1:2], theta[1:2], omega[1:2])
    assert evs[0]["s"].shape == (1, 360) and evs[1]["s"].shape == (4, 360)
    for nm, a in full.items():  # an unlike design: the N-vane kernel's own bits
        assert np.array_equal(evs[1][nm], a[0], equal_nan=True), nm


def test_the_numpy_ellipse_is_the_compiled_housing_curve(four):
    kern, P, theta, omega, one = four
    dm_index = {nm: i for i, nm in enumerate(layout_names(kern.structure))}
    alpha, pts, margin = screen.housing_samples(P, dm_index, 360)
    for d in range(len(P)):
        a2, p2, _ = housing_check_samples(kern, P[d], 360)
        assert np.array_equal(alpha, a2)
        assert np.abs(pts[d] - p2).max() < 1e-3 * margin[d]  # rounding, far inside the margin


def test_a_clearance_within_the_margin_is_left_undecided():
    n = 8
    ang = np.linspace(0, 2 * math.pi, n, endpoint=False)
    pts = np.stack([np.cos(ang), np.sin(ang)])[None] * 0.0225
    s, res = np.full((1, 1, n), 1e-3), np.zeros((1, 1, n))
    args = (np.array([0.012]), np.array([0.011]), pts, None, s, res)
    rr = 0.0225 * (1 - 1e-14)
    assert screen.geometry_ok(np.array([rr]), *args)[0]
    assert not screen.geometry_ok(np.array([rr]), *args, margin=1e-12 * 0.045)[0]


def _rows(study, every_vane):
    from pumpsim.design.execute import run_study

    with pytest.MonkeyPatch.context() as mp:
        if every_vane:
            mp.setattr(evaluate, "one_vane", lambda st: None)
        return run_study(study, workers=0, progress=False)[0]


SCALE_OF = {"ptp_torque": "rms_torque", "slot_friction_power": "friction_power"}  # a zero in exact arithmetic


@pytest.mark.parametrize("study", [
    {"study": {"config": str(EXAMPLES / "test_rig.toml"), "sampler": "sobol", "samples": 64, "seed": 3},
     "vary": {"housing.radius": {"distribution": "normal", "sd": 4e-6},
              "vane.length": {"distribution": "normal", "sd": 5e-6},
              "friction.housing.dynamic": {"distribution": "uniform", "low": 0.12, "high": 0.28}}},
    {"study": {"config": str(EXAMPLES / "ellipse_4vanes.toml"), "sampler": "grid"},
     "vary": {"housing.b": {"values": [0.0245, 0.022273, 0.020417]}, "rotor.vanes": {"values": [2, 3, 5, 6]}}}])
def test_study_rows_equal_the_every_vane_rows_within_the_kernels_rounding(study):
    s = study_from_dict(study)
    a, b = _rows(s, False), _rows(s, True)
    assert list(a.columns) == list(b.columns) and (a["status"] == b["status"]).all()
    assert (a["status"] != "ok").any() or "ellipse" not in s.config_path
    for c in a.columns:
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if x.dtype.kind != "f":
            assert (x == y).all(), c
            continue
        assert (np.isnan(x) == np.isnan(y)).all(), c
        m = ~np.isnan(x)
        scale = np.abs(b[SCALE_OF.get(c, c)].to_numpy()[m]).max() if m.any() else 0.0
        assert np.abs(x[m] - y[m]).max(initial=0.0) <= SIMD_REL * scale, c


def test_one_vane_is_found_for_its_structure(four):
    kern, *_, one = four
    assert one.structure == kern.structure and one.fast.structure == dataclasses.replace(kern.structure, vanes=1)


@pytest.mark.slow  # builds the out-of-round housing's SIMD variant (~40 s on a fresh machine)
def test_an_out_of_round_housing_goes_the_same_way_with_its_compiled_curve(tmp_path):
    text = (EXAMPLES / "test_rig.toml").read_text().replace(
        "[housing]\n", "[housing]\nharmonics = [[3, 3.0e-5, 0.3]]\n").replace("center = [0.0, 0.0]", "center = [4e-4, 2e-4]")
    (tmp_path / "rig.toml").write_text(text)
    s = study_from_dict({"study": {"config": str(tmp_path / "rig.toml"), "sampler": "random", "samples": 24, "seed": 1},
                         "vary": {"vane.mass": {"distribution": "normal", "sd": 0.05, "relative": True},
                                  "friction.housing.dynamic": {"distribution": "uniform", "low": 0.1, "high": 0.3}}})
    from pumpsim.design.execute import study_designs
    from pumpsim.design.vector import design_maps

    maps, rest = design_maps(s, study_designs(s))
    assert maps and maps[0][0].structure.harmonics == 1 and not len(rest)
    a, b = _rows(s, False), _rows(s, True)
    assert (a["status"] == "ok").all() and (b["status"] == "ok").all()
    for c in ("mean_torque", "max_normal_force", "friction_power_2"):
        assert np.abs(a[c] - b[c]).max() <= SIMD_REL * np.abs(b[c]).max(), c
    assert np.abs(a["ptp_torque"] - b["ptp_torque"]).max() <= SIMD_REL * np.abs(b["rms_torque"]).max()


def test_the_batch_screen_finds_the_rotor_axis_inside_as_the_polygon_rule_does():
    from pumpsim.geometry import _point_in_polygon

    rng = np.random.default_rng(5)
    n, B = 36, 40
    ang = np.sort(rng.uniform(0, 2 * math.pi, (B, n)), axis=1)
    r = rng.uniform(0.8, 1.2, (B, n))
    c = rng.uniform(-1.5, 1.5, (B, 2, 1))
    pts = np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1) + c
    s, res = np.full((B, 1, n), 1e-3), np.zeros((B, 1, n))
    ok = screen.geometry_ok(np.full(B, 1e-9), np.full(B, 0.012), np.full(B, 0.011), pts, None, s, res)
    want = [_point_in_polygon(0.0, 0.0, p[0], p[1]) for p in pts]
    assert ok.tolist() == want and 0 < sum(want) < B


def test_the_ellipse_closed_form_admits_only_what_the_samples_admit():
    rng = np.random.default_rng(11)
    B, n = 4000, 360
    names = ("housing.a", "housing.b", "housing.center.0", "housing.center.1", "housing.angle")
    index = {k: i for i, k in enumerate(names)}
    a = rng.uniform(0.02, 0.03, B)
    b = a / np.where(np.arange(B) % 2, rng.uniform(1.0, 1.4, B), 1.0)  # half of them round bores
    off = rng.uniform(0.0, 1.05, B) * b  # some centres put the rotor axis outside
    off[np.arange(B) % 4 == 1] = 0.0  # and a quarter concentric ellipses
    phi = rng.uniform(-math.pi, math.pi, B)
    P = np.column_stack([a, b, off * np.cos(phi), off * np.sin(phi), rng.uniform(-1, 1, B)])
    _, pts, margin = screen.housing_samples(P, index, n)
    gap = np.hypot(pts[:, 0], pts[:, 1]).min(axis=1)  # the samples' own clearance
    rr = gap * rng.choice([0.999, 1 - 1e-9, 1 - 1e-13, 1.0, 1 + 1e-9], B)  # most at the edge
    exact = screen.polygon_clear(rr, pts, None, margin)
    fast = screen.ellipse_clear(P, index, rr, n)
    assert not (fast & ~exact).any()  # never admits a design the samples reject
    assert exact.any() and not exact.all()
    # a round bore (the bound is its exact clearance; the samples' chords cut up to 4e-5 of its
    # radius) or a concentric ellipse is decided 0.1 % from the edge; an eccentric ellipse's bound
    # is looser (then the samples decide)
    plain = (a == b) | (off == 0.0)
    assert fast[plain & (rr <= 0.999 * gap) & (off < 0.8 * b)].all()
