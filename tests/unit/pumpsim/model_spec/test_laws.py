"""The friction law against spec §3, from an independent expectation: hand-evaluated points and a
scalar transcription of the spec's formula (not the project's implementation)."""
import numpy as np
import pytest

from pumpsim.model_spec import laws
from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config, one_revolution
from tests.tolerances import CONTINUITY_MARGIN, LAW_ABS

MU_S, MU_D, V_S, V_D = 0.3, 0.2, 0.01, 0.1


def spec_step(x, x0, h0, x1, h1):
    """Spec §3: STEP = h0 + (h1 - h0) D^2 (3 - 2 D), D = (x - x0)/(x1 - x0) clamped to [0, 1]."""
    d = min(max((x - x0) / (x1 - x0), 0.0), 1.0)
    return h0 + (h1 - h0) * d * d * (3 - 2 * d)


def spec_mu(v, mu_s, mu_d, v_s, v_d):
    """Spec §3, case by case."""
    v = float(v)
    sign = (v > 0) - (v < 0)
    if abs(v) <= v_s:
        return spec_step(v, -v_s, -mu_s, v_s, mu_s)
    if abs(v) <= v_d:
        return sign * spec_step(abs(v), v_s, mu_s, v_d, mu_d)
    return sign * mu_d


# (v, mu) evaluated by hand: D = 0.5 at v = 0 gives 0; D = 0.75 at v_s/2 gives -0.3 + 0.6 * 0.84375;
# halfway between v_s and v_d D = 0.5 gives the mean of the COFs; D = 0.25 gives 0.3 - 0.1 * 0.15625
HAND = [(0.0, 0.0), (0.005, 0.20625), (-0.005, -0.20625), (0.01, 0.3), (-0.01, -0.3),
        (0.055, 0.25), (0.0325, 0.284375), (0.1, 0.2), (1.0, 0.2), (-3.0, -0.2)]


@pytest.mark.parametrize("v,mu", HAND)
def test_friction_law_at_hand_evaluated_points(v, mu):
    assert float(laws.friction_coefficient(np.array(v), MU_S, MU_D, V_S, V_D)) == pytest.approx(mu, abs=LAW_ABS)
    assert spec_mu(v, MU_S, MU_D, V_S, V_D) == pytest.approx(mu, abs=LAW_ABS)


def test_step_is_the_clamped_cubic():
    x = np.linspace(-0.5, 1.5, 41)
    got = laws.step(x, 0.0, 1.0, 1.0, 3.0)
    assert np.allclose(got, [spec_step(xi, 0.0, 1.0, 1.0, 3.0) for xi in x], atol=LAW_ABS, rtol=0)
    assert float(laws.step(np.array(0.3), 0.0, 1.0, 1.0, 3.0)) == pytest.approx(1.432, abs=LAW_ABS)


def test_friction_law_is_odd_continuous_and_matches_the_spec_everywhere():
    v = np.concatenate([np.linspace(-0.2, 0.2, 4001), [V_S, -V_S, V_D, -V_D]])
    mu = laws.friction_coefficient(v, MU_S, MU_D, V_S, V_D)
    assert np.allclose(mu, [spec_mu(x, MU_S, MU_D, V_S, V_D) for x in v], atol=LAW_ABS, rtol=0)
    assert np.allclose(laws.friction_coefficient(-v, MU_S, MU_D, V_S, V_D), -mu, atol=LAW_ABS, rtol=0)
    # continuous: on a 1e-4 m/s grid the largest jump is the cubic's slope x step (1.5 * 0.6 / 0.02)
    assert np.max(np.abs(np.diff(mu[:4001]))) < 1.5 * 2 * MU_S / (2 * V_S) * 1e-4 * CONTINUITY_MARGIN


def test_compiled_kernel_uses_the_spec_law_for_the_slot():
    """The compiled mu_slot at each sample equals the spec's law at the compiled slide speed: the
    slot slide reverses twice a revolution on the ellipse, so the cubic branches are crossed."""
    cfg = make_config("ellipse_4vanes", **{"friction.housing.v_static": 0.02, "friction.housing.v_dynamic": 0.2})
    kern, p, pv = kernel_and_p(cfg)
    out = inverse_dynamics(kern, p, one_revolution(4096), cfg.speed, 0.0)
    v = pv.values
    args = [v["friction.slot.static"], v["friction.slot.dynamic"], v["friction.slot.v_static"],
            v["friction.slot.v_dynamic"]]  # spelled out: the test does not use the code's key tuple
    sdot, mu = out["sdot"].ravel(), out["mu_slot"].ravel()
    inside = np.abs(sdot) < args[3]
    assert inside.sum() > 20  # the transition region is sampled
    assert np.allclose(mu, [spec_mu(x, *args) for x in sdot], atol=LAW_ABS, rtol=0)
