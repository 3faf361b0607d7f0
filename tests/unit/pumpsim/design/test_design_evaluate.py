"""The batched kernel call of a design study: a design's outputs do not depend on its batch."""
import numpy as np

from pumpsim.design import evaluate
from pumpsim.design.evaluate import evaluate_designs, revolution
from tests.conftest import kernel_and_p, make_config


def _designs():
    """Five ellipse designs: different semi-axes, COFs and start angles, at different speeds."""
    cfgs = [make_config("test_rig", **{"housing.radius": None, "housing.shape": "ellipse",
                                       "housing.a": 0.0225 + 2e-4 * k, "housing.b": 0.0225 - 1e-4 * k,
                                       "friction.housing.dynamic": 0.1 + 0.03 * k})
            for k in range(5)]
    kern = kernel_and_p(cfgs[0])[0]
    P = np.array([kernel_and_p(c)[1] for c in cfgs])
    theta = np.array([revolution(0.1 * k, 90) for k in range(5)])
    return kern, P, theta, np.array([300.0, 410.0, 520.0, 630.0, 740.0])


def test_a_batch_gives_each_design_the_bits_it_gets_alone():
    kern, P, theta, omega = _designs()
    batch = evaluate_designs(kern, P, theta, omega)
    for d in range(len(P)):
        alone = evaluate_designs(kern, P[d:d + 1], theta[d], omega[d:d + 1])
        for name, arr in batch.items():
            assert np.array_equal(arr[d], alone[name][0]), name


def test_the_simd_batch_agrees_with_the_scalar_kernel(monkeypatch):
    kern, P, theta, omega = _designs()
    fast = evaluate_designs(kern, P, theta, omega)
    monkeypatch.setenv("PUMPSIM_DESIGN_KERNEL", "scalar")
    evaluate._MAPS.cache.clear()
    scalar = evaluate_designs(kern, P, theta, omega)
    evaluate._MAPS.cache.clear()
    scale = np.abs(scalar["torque"]).max()
    # two compilations of the same expressions: rounding differences only
    assert np.abs(fast["torque"] - scalar["torque"]).max() < 1e-10 * scale
    assert np.abs(fast["normal"] - scalar["normal"]).max() < 1e-10 * np.abs(scalar["normal"]).max()
