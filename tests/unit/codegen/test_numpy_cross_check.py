"""The CasADi assembly against an independent NumPy assembly of the same SymPy mechanics
(2x2 Newton in (s, alpha) instead of the kernel's scalar Newton in alpha)."""
import numpy as np

from pumpsim.codegen.numpy_model import NumpyConstrainedModel
from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config, one_revolution
from tests.tolerances import NUMPY_CROSS_REL


def test_numpy_assembly_matches_compiled_kernel():
    cfg = make_config("ellipse_4vanes", **{"housing.harmonics": [[3, 3e-5, 0.1]], "rotor.slot_tilt": 0.1,
                                           "vane.tip_radius": 0.001, "housing.center": [2e-4, -1e-4]})
    kern, p, pv = kernel_and_p(cfg)
    theta = one_revolution(500)
    tq, normal = NumpyConstrainedModel(pv.structure).inverse_dynamics(theta, cfg.speed, 250.0, p)
    out = inverse_dynamics(kern, p, theta, cfg.speed, 250.0)
    np.testing.assert_allclose(out["torque"], tq, rtol=NUMPY_CROSS_REL)
    np.testing.assert_allclose(out["normal"], normal, rtol=NUMPY_CROSS_REL)
