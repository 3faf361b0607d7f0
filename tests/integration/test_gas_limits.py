"""Where the gas model departs from the spec's closed forms, and the pump-down's tolerances over the
whole range of the wall heat exchange (spec §8; docs/explanation/gas-model.md)."""
import math

import numpy as np
import pytest

from pumpsim.model_spec.parameters import GAS_PARAMETERS
from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.pneumatics import run
from pumpsim.kernels.pneumatic import kernels, parameter_vector
from pumpsim.tolerances import PUMPDOWN_ATOL, PUMPDOWN_RTOL
from tests.pneumatic_helpers import IDEAL, evp_config, speed_config
from tests.tolerances import PUMPDOWN_RANGE_REL, QUASI_STATIC_GRID, ULTIMATE_PRESSURE_REL

# the EVP example's windows: the exhaust is longer than the vanes' spacing less a tip, so the two
# cells beside a vane share it while the vane crosses it
EVP_WINDOWS = {"ports.inlet": [-2.356, -0.785], "ports.exhaust": [1.2, 2.356]}


def quasi_static_ultimate(cfg, n=QUASI_STATIC_GRID):
    """Isothermal ultimate pressure of ideal openings (every connected volume at one pressure at
    once), marched over the revolution on n angles from the compiled cell geometry: the cells over
    the exhaust window and the exhaust port share a pressure, vented to the atmosphere above it
    (check valve); the cells over the inlet window and the manifold share one, refilled from the
    booster below p_b (booster check valve); closed cells keep their gas. The ultimate is the
    highest p_b from which the periodic cycle draws nothing. The march starts at the atmosphere,
    so the trapped gas is the most the exhaust lets through (a cycle that never vents would keep
    any smaller charge); 5 revolutions settle it (7205.2 Pa; 8: 7204.8 Pa). Returns (p_u, V_min,
    V_max)."""
    k, p = kernels(cfg), parameter_vector(cfg)
    v = dict(zip(run._names(k.structure), p))
    geo = [k["cell_geometry"](t, p) for t in np.linspace(0, 2 * math.pi, n, endpoint=False)]
    V = np.array([np.asarray(g[0]).ravel() for g in geo])
    inlet = np.array([np.asarray(g[3]).ravel() for g in geo]) > 0
    exhaust = np.array([np.asarray(g[4]).ravel() for g in geo]) > 0
    assert not (inlet & exhaust).any()  # no cell spans both windows: no direct blow-by
    p_atm, V_ex, V_in = v["gas.atmosphere"], v["ports.exhaust_volume"], v["ports.inlet_volume"]

    def drawn(p_b, revolutions=5):  # p V drawn from the booster over the last revolution
        pv, pv_ex, pv_in = p_atm * V[0], p_atm * V_ex, p_b * V_in
        for _ in range(revolutions):
            total = 0.0
            for Vj, E, I in zip(V, exhaust, inlet):
                if E.any():
                    pe = min((pv[E].sum() + pv_ex) / (Vj[E].sum() + V_ex), p_atm)
                    pv[E], pv_ex = pe * Vj[E], pe * V_ex
                pi = (pv[I].sum() + pv_in) / (Vj[I].sum() + V_in)
                if pi < p_b:
                    total += (p_b - pi) * (Vj[I].sum() + V_in)
                    pi = p_b
                pv[I], pv_in = pi * Vj[I], pi * V_in
        return total

    lo, hi = 0.0, p_atm
    while hi - lo > 1e-4 * hi:
        mid = 0.5 * (lo + hi)
        if drawn(mid) > 1e-12 * p_atm * V.max():
            hi = mid
        else:
            lo = mid
    return hi, V.min(), V.max()


def test_ultimate_pressure_follows_the_quasi_static_cycle_not_isolated_cells():
    """The EVP geometry with ideal openings, isothermal: the full model's ultimate pressure is the
    quasi-static cycle's (cells sharing the exhaust window across a vane), not the spec's isolated
    cells' p_atm V_d / V_max -- the shared window lets the dead-volume gas into the cell behind,
    which carries it out again. At 25 rad/s the finite opening flows leave ~0.5 %."""
    cfg = speed_config(25.0, **{**IDEAL, **EVP_WINDOWS, "ports.exhaust_volume": 1e-9,
                                "booster.volume": 5e-6})
    p_u, V_d, V_max = quasi_static_ultimate(cfg)
    isolated = cfg.pneumatic.values["gas.atmosphere"] * V_d / V_max
    assert p_u < 0.8 * isolated  # the departure the docs state, computed
    # rtol 1e-7: at 1e-6 the booster pressure's integration error (~1e-4 here, moved by rounding-
    # level changes of the kernel) is as large as the settling bound; at 1e-7 it is ~3e-6, and the
    # run takes no more steps
    r = run.integrate(cfg, 6.0, 20, rtol=1e-7, atol=1e-9)
    pb = r.outputs["booster_pressure"]
    assert abs(pb[-1] - pb[-20]) < 1e-4 * pb[-1]  # settled over the last second
    assert pb[-1] == pytest.approx(p_u, rel=ULTIMATE_PRESSURE_REL)


H_RANGE_END = next(q for q in GAS_PARAMETERS if q.name == "gas.heat_transfer").upper.value


@pytest.mark.parametrize("h", [100.0, H_RANGE_END])
def test_pumpdown_tolerances_converge_over_the_heat_transfer_range(h):
    """A 1 L booster 101.3 -> 30 kPa at the example's film coefficient and at the registry's
    largest: the default tolerances' time to target and energy within PUMPDOWN_RANGE_REL of a run
    100x tighter (~10 s each)."""
    assert math.isfinite(H_RANGE_END)
    cfg = evp_config(**{"booster.volume": 1.0e-3, "gas.heat_transfer": h})
    default = pdm.pumpdown(cfg)
    tight = pdm.pumpdown(cfg, rtol=PUMPDOWN_RTOL / 100, atol=PUMPDOWN_ATOL / 100)
    for key in ("time_to_target", "energy"):
        assert default.summary[key] == pytest.approx(tight.summary[key], rel=PUMPDOWN_RANGE_REL), key
