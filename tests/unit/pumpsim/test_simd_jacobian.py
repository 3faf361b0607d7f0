"""The SIMD library's Jacobian entries (codegen/simd_jacobian.py, FastInverseDynamics.jacobian)
against forward AD on the CasADi map of the scalar kernel and against central differences of the
SIMD torque: the ellipse (tilted slots, round tips), with housing harmonics, and the test rig."""
import casadi as ca
import numpy as np
import pytest

from pumpsim.errors import ConfigError
from pumpsim.kernels import simd as kernel_simd
from tests.conftest import kernel_and_p, make_config
from tests.tolerances import SIMD_JACOBIAN_FD_REL, SIMD_JACOBIAN_REL, SIMD_JACOBIAN_ZERO

CASES = {
    "ellipse": ("ellipse_4vanes", {"rotor.slot_tilt": 0.1, "vane.tip_radius": 0.001}),
    "harmonics": ("ellipse_4vanes", {"housing.harmonics": [[3, 3e-5, 0.1], [5, 1e-5, 0.7]]}),
    "test_rig": ("test_rig", {}),
}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    base, changes = CASES[request.param]
    kern, p, pv = kernel_and_p(make_config(base, **changes))
    fk = kernel_simd.load_fast_kernel(pv.structure, fallback=False)
    assert fk.has_jacobian
    return kern, fk, p, pv


def motion(rng, n, speed=471.0):
    """Angles over several turns, speeds around the operating one (both signs, some near standstill)
    and accelerations."""
    theta = rng.uniform(0, 6 * np.pi, n)
    omega = speed * rng.uniform(0.5, 1.3, n) * np.where(rng.random(n) < 0.2, -1, 1)
    omega[: n // 20] = rng.uniform(-0.02, 0.02, n // 20)
    return theta, omega, rng.normal(0, 2e4, n)


def map_jacobian(kern, p, theta, omega, omegadot, seeds):
    """Torque and its derivatives along `seeds` by forward AD (jtimes) on the scalar kernel's map."""
    n, nd = theta.size, seeds.shape[0]
    th, om, od = (ca.MX.sym(s) for s in ("theta", "omega", "omegadot"))
    pp, S = ca.MX.sym("p", p.size), ca.MX.sym("S", 3 + p.size, nd)
    tq = kern["inverse_dynamics"](th, om, od, pp)[0]
    f = ca.Function("torque_directions", [th, om, od, pp, S], [tq, ca.jtimes(tq, ca.vertcat(th, om, od, pp), S)])
    T, D = f.map(n)(theta[None], omega[None], omegadot[None], p[:, None], np.tile(seeds.T, (1, n)))
    return np.asarray(T).ravel(), np.asarray(D).reshape(n, nd).T


def test_every_direction_equals_forward_ad_on_the_casadi_map(case):
    """Each derivative to SIMD_JACOBIAN_REL of its largest value, plus, for a derivative zero in
    exact arithmetic (the centre of a concentric or 4-vane housing, theta on a circle), rounding noise
    below SIMD_JACOBIAN_ZERO of the torque over the input's size (>= the housing's): the reverse
    sweep sums the vanes' cancelling contributions in another order than the forward one."""
    kern, fk, p, pv = case
    theta, omega, omegadot = motion(np.random.default_rng(5), 2001)
    seeds = np.eye(3 + p.size)  # d/dtheta, d/domega, d/domegadot and every parameter
    tq, D = fk.jacobian(theta, omega, omegadot, p, seeds)
    rt, rD = map_jacobian(kern, p, theta, omega, omegadot, seeds)
    assert np.max(np.abs(tq - rt)) <= SIMD_JACOBIAN_REL * np.max(np.abs(rt))
    size = np.maximum(np.abs(np.r_[2 * np.pi, 471.0, 2e4, p]), max(pv.values["housing.a"], pv.values["housing.b"]))
    bound = SIMD_JACOBIAN_REL * np.max(np.abs(rD), axis=1) + SIMD_JACOBIAN_ZERO * np.max(np.abs(rt)) / size
    excess = np.max(np.abs(D - rD), axis=1) / bound
    names = ["theta", "omega", "omegadot", *pv.names]
    assert excess.max() <= 1.0, (names[int(np.argmax(excess))], excess.max())
    assert np.count_nonzero(np.max(np.abs(rD), axis=1) > 1e3 * bound) >= 10  # not a test of zeros


def test_combined_directions_equal_central_differences(case):
    """Directions mixing the inputs (as the fits' seed columns do) against central differences of
    the SIMD torque (step 1e-6 of each input's size). A friction reversal or a lift-off within the
    step is a jump no difference quotient follows: with 5 % of the samples near standstill and
    reversals each revolution, observed 0-3 % such samples; everywhere else the difference agrees to
    its truncation and rounding (median 1e-13 to 1e-7 of the column's scale)."""
    _, fk, p, _ = case
    rng = np.random.default_rng(8)
    theta, omega, omegadot = motion(rng, 3001)
    u0 = np.r_[1.0, 471.0, 2e4, np.where(p != 0, np.abs(p), 1e-3)]
    seeds = rng.normal(size=(4, u0.size)) * u0 * (rng.random((4, u0.size)) < 0.3)
    _, D = fk.jacobian(theta, omega, omegadot, p, seeds)
    h = 1e-6

    def torque(step, d):
        s = step * seeds[d]
        return fk(theta + s[0], omega + s[1], omegadot + s[2], p + s[3:], outputs="torque")["torque"]

    for d in range(seeds.shape[0]):
        err = np.abs((torque(h, d) - torque(-h, d)) / (2 * h) - D[d]) / np.max(np.abs(D[d]))
        assert np.mean(err <= SIMD_JACOBIAN_FD_REL) >= 0.95, (d, np.mean(err <= SIMD_JACOBIAN_FD_REL))
        assert np.median(err) <= SIMD_JACOBIAN_FD_REL


def test_blocks_samples_and_threads_give_the_same_bits(case):
    _, fk, p, _ = case
    rng = np.random.default_rng(2)
    n = 2 * 512 + 77  # chunks and a ragged tail
    theta, omega, omegadot = motion(rng, n)
    seeds = rng.normal(size=(3, 3 + p.size))
    tq, D = (a.copy() for a in fk.jacobian(theta, omega, omegadot, p, seeds))
    assert np.array_equal(tq, fk(theta, omega, omegadot, p, outputs="torque")["torque"])
    out = fk.jacobian_array(n, 3)
    for kw in ({"threads": 2, "out": out}, {"p": np.tile(p, (3, 1)), "block": 512}):
        args = {"p": p, **kw}
        t2, D2 = fk.jacobian(theta, omega, omegadot, args.pop("p"), seeds, **args)
        assert np.array_equal(t2, tq) and np.array_equal(D2, D), kw
    # one vector per sample: the per-sample loop (its own FMA contraction), equal to rounding
    t3, D3 = fk.jacobian(theta, omega, omegadot, np.tile(p, (n, 1)), seeds, threads=2)
    assert np.max(np.abs(t3 - tq)) <= SIMD_JACOBIAN_REL * np.max(np.abs(tq))
    assert np.all(np.max(np.abs(D3 - D), axis=1) <= SIMD_JACOBIAN_REL * np.max(np.abs(D), axis=1) + 1e-300)
    P = np.tile(p, (2, 1))
    P[1] *= 1.01
    tb, Db = fk.jacobian(theta, omega, omegadot, P, seeds, block=600)
    t1, D1 = fk.jacobian(theta[600:], omega[600:], omegadot[600:], P[1], seeds)
    assert np.array_equal(tb[600:], t1) and np.array_equal(Db[:, 600:], D1)


def test_bad_seeds_and_buffers_are_named(case):
    _, fk, p, _ = case
    theta = np.linspace(0, 1, 10)
    with pytest.raises(ConfigError, match="seeds"):
        fk.jacobian(theta, 471.0, 0.0, p, np.zeros((2, p.size)))
    with pytest.raises(ConfigError, match="jacobian_array"):
        fk.jacobian(theta, 471.0, 0.0, p, np.zeros((2, 3 + p.size)), out=np.empty((2, 10)))
