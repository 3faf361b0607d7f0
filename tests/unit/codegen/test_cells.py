"""Cell geometry (spec §8): the volume identity, the concentric closed form, dV/dtheta and the
port overlaps, for ellipse, eccentric and harmonic housings with tilted slots."""
import math

import numpy as np
import pytest
from scipy.integrate import quad

from pumpsim.kernels.pneumatic import kernels, parameter_vector
from tests.conftest import EXAMPLES
from tests.pneumatic_helpers import ellipse_radius, gas_config
from tests.tolerances import CELL_DERIVATIVE_REL, CELL_IDENTITY_REL, PORT_ARC_REL

HOUSINGS = {
    "ellipse": {},
    "eccentric_tilted": {"housing.center": [0.0011, -0.0004], "housing.angle": 0.4,
                         "rotor.slot_tilt": 0.2, "rotor.first_slot_angle": 0.3},
    "harmonic_tilted_round_tip": {"housing.harmonics": [[3, 3e-5, 0.2], [7, 1e-5, 1.0]],
                                  "housing.center": [0.0006, 0.0003], "rotor.slot_tilt": -0.15,
                                  "vane.tip_radius": 0.002},
}


def _geometry(cfg, theta, **over):
    k = kernels(cfg)
    p = parameter_vector(cfg, **over)
    out = k["cell_geometry"](theta, p)
    return [np.asarray(o).ravel() for o in out], p


def _vane_area_outside_rotor(s, phi, v):
    """Area of vane rectangle (flat or rounded end) outside the rotor circle: 1-D integral across
    the thickness of (tip end - rotor circle) along the slot direction."""
    rb, beta, Rr = v["rotor.slot_radius"], v["rotor.slot_tilt"], v["rotor.radius"]
    L, h, rho = v["vane.length"], v["vane.thickness"], v["vane.tip_radius"]
    ob = rb * np.array([math.cos(phi), math.sin(phi)])
    u = np.array([math.cos(phi + beta), math.sin(phi + beta)])
    w = np.array([-u[1], u[0]])

    def length(c):
        q = ob + c * w
        qu = q @ u
        a_rotor = -qu + math.sqrt(qu * qu - q @ q + Rr * Rr)
        top = s + L if rho == 0 else s + L - rho + math.sqrt(rho * rho - c * c)
        return top - a_rotor

    return quad(length, -h / 2, h / 2, epsabs=0, epsrel=1e-13, limit=200)[0]


# the harmonic housing builds its own gas kernel (about a minute of C compile on a fresh machine)
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if "harmonic" in n else n
                                  for n in HOUSINGS])
def test_volume_identity_every_angle(name):
    cfg = gas_config(**HOUSINGS[name])
    v = {**cfg.values}
    W = 0.02
    a, b, psi = v["housing.a"], v["housing.b"], v["housing.angle"]
    harm = cfg.harmonics
    housing_area = quad(lambda al: 0.5 * ellipse_radius(al, a, b, psi, harm) ** 2, 0, 2 * math.pi,
                        epsabs=0, epsrel=1e-13, limit=400)[0]
    annulus = (housing_area - math.pi * v["rotor.radius"] ** 2) * W
    N = cfg.vanes
    for theta in np.linspace(0, 2 * math.pi, 17):
        (V, dV, vv, lin, lex, s, al, res, *_), _ = _geometry(cfg, theta)
        assert np.all(V > 0)
        assert V.sum() + vv.sum() == pytest.approx(annulus, rel=CELL_IDENTITY_REL)
        for i in range(N):
            phi = v["rotor.first_slot_angle"] + 2 * math.pi * i / N
            assert vv[i] == pytest.approx(_vane_area_outside_rotor(s[i], phi, v) * W,
                                          rel=CELL_IDENTITY_REL)


@pytest.mark.parametrize("vanes", [1, 4])
def test_concentric_thin_radial_vanes_constant_volume(vanes):
    R, Rr, W = 0.0225, 0.020, 0.02
    cfg = gas_config("test_rig", **{"rotor.vanes": vanes, "effects": {}})
    exact = math.pi * (R**2 - Rr**2) * W / vanes
    for theta in np.linspace(0, 2 * math.pi, 9):
        (V, dV, *_), _ = _geometry(cfg, theta, vane__thickness=0.0)
        np.testing.assert_allclose(V, exact, rtol=CELL_IDENTITY_REL)
        assert np.max(np.abs(dV)) < CELL_IDENTITY_REL * exact


@pytest.mark.parametrize("name", list(HOUSINGS))
def test_volume_derivative_matches_finite_difference(name):
    cfg = gas_config(**HOUSINGS[name])
    h = 1e-5
    for theta in np.linspace(0.1, 2 * math.pi, 7):
        (V, dV, *_), _ = _geometry(cfg, theta)
        Vp = _geometry(cfg, theta + h)[0][0]
        Vm = _geometry(cfg, theta - h)[0][0]
        np.testing.assert_allclose(dV, (Vp - Vm) / (2 * h), atol=CELL_DERIVATIVE_REL * V.max())


def test_port_overlaps_tile_the_window():
    """The cells' housing arcs tile the housing, so their overlaps with a window add up to the
    window's arc length (vane tips touch at points)."""
    cfg = gas_config(**HOUSINGS["harmonic_tilted_round_tip"])
    v = cfg.values
    a, b, psi = v["housing.a"], v["housing.b"], v["housing.angle"]

    def speed(al):
        r = ellipse_radius(al, a, b, psi, cfg.harmonics)
        e = 1e-6
        dr = (ellipse_radius(al + e, a, b, psi, cfg.harmonics)
              - ellipse_radius(al - e, a, b, psi, cfg.harmonics)) / (2 * e)
        return math.hypot(r, dr)

    for name, (lo, hi) in (("inlet", (0.3, 2.0)), ("exhaust", (3.5, 5.5))):
        arc = quad(speed, lo + psi, hi + psi, epsrel=1e-12, limit=200)[0]
        for theta in np.linspace(0, 2 * math.pi, 5):
            (V, dV, vv, lin, lex, *_), _ = _geometry(cfg, theta)
            total = (lin if name == "inlet" else lex).sum()
            assert total == pytest.approx(arc, rel=PORT_ARC_REL)


def _slot_mouth_pocket(M, pump, vane, side):
    """Area of the slot mouth's pocket beside a retracted full-round tip (zero when the flank
    reaches past the rotor): bounded by the slot wall from the flank's end J to the rotor circle
    (R), the rotor circle from R to where the tip crosses it (X), and the tip from X back to J.
    Independent of codegen: the independent model's slot frame, circle arcs in closed form."""
    off = vane.Ob + side * pump.h / 2 * vane.w
    bo = off @ vane.u
    R = off + (-bo + math.sqrt(bo * bo - (off @ off - pump.Rr ** 2))) * vane.u
    J = vane.P + side * pump.rho * vane.w
    if J @ J >= pump.Rr ** 2:
        return 0.0
    X = M._circle_cut(vane.P, pump.rho, pump.Rr, side * vane.w)

    def about(c, x):
        return math.atan2(x[1] - c[1], x[0] - c[0])

    tJ, tX = about(vane.P, J), about(vane.P, X)
    rX, rR = about((0.0, 0.0), X), about((0.0, 0.0), R)
    green = (0.5 * (R[0] * J[1] - R[1] * J[0]) + M._arc_green(vane.P, pump.rho, tJ, tJ + M._wrap(tX - tJ))
             + M._arc_green((0.0, 0.0), pump.Rr, rX, rX + M._wrap(rR - rX)))
    return abs(green)


def test_a_retracted_tips_slot_mouth_pocket_is_not_cell_gas():
    """Near top dead centre the EVP's full-round vanes are so far in their slots that the flanks
    end inside the rotor and only the tip cap protrudes; beside the cap, the slot's mouth is a
    pocket below the rotor circle. The spec bounds every cell by the rotor circle, so the pocket
    is no cell's gas: pumpsim's cells equal an independent boundary-integral implementation's
    (which reads the spec so) at nine angles, and the same implementation with the pocket counted
    is larger by exactly the pockets' closed-form areas (so the pockets are not empty there)."""
    from dataclasses import replace

    from bench.independent_gas import model as M
    from tests.pneumatic_helpers import evp_config

    cfg = evp_config()
    pump = M.load(EXAMPLES / "evp_booster.toml")
    assert not pump.pocket_in_cell
    counted = replace(pump, pocket_in_cell=True)
    with_pocket = 0
    for theta in np.linspace(0, math.pi / 2, 9):
        (V, *_), _ = _geometry(cfg, theta)
        vanes = [M.Vane(pump, i, theta) for i in range(pump.N)]
        pockets = [[_slot_mouth_pocket(M, pump, v, s) for s in (1, -1)] for v in vanes]
        np.testing.assert_allclose(V, [c[0] for c in M.cells(pump, theta, vanes)],
                                   rtol=CELL_IDENTITY_REL)
        big = [c[0] for c in M.cells(counted, theta, [M.Vane(counted, i, theta) for i in range(pump.N)])]
        want = [V[i] + pump.W * (pockets[i][0] + pockets[(i + 1) % pump.N][1]) for i in range(pump.N)]
        np.testing.assert_allclose(big, want, rtol=CELL_IDENTITY_REL)
        with_pocket += sum(a > 0 for pk in pockets for a in pk)
    assert with_pocket > 0  # the case this test is about occurs
