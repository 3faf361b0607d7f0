"""The independent model against pumpsim's compiled kernels term by term, at identical states:
the cell geometry (volumes, dV/dtheta, window overlaps, exposed flanks), every flow at the same
effective area, and the mechanics (shaft acceleration, tip normal forces, slot reactions).

    python bench/independent_gas/terms.py [--config bench/independent_gas/evp_small_booster.toml]
        [--pocket-in-cell]

Prints per term the largest difference relative to the term's size over the states. The states:
a few shaft angles with cell pressures 30-120 kPa, temperatures 280-340 K, the plenums (each with
its own temperature) and the booster apart. --pocket-in-cell counts the slot mouth beside a retracted tip as cell gas (not the
spec's reading, nor pumpsim's).
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import model as M  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from pumpsim.config import load_config  # noqa: E402
from pumpsim.kernels.pneumatic import kernels, parameter_vector  # noqa: E402

CONFIG = Path(__file__).resolve().parent / "evp_small_booster.toml"
# (theta, omega, current, cell pressures, cell temperatures, inlet, exhaust, booster pressure,
# inlet and exhaust plenum temperatures)
STATES = [
    (0.7, 500.0, 15.0, [40e3, 60e3, 110e3, 80e3], [300.0, 310.0, 330.0, 320.0], 39e3, 104e3, 41e3, 285.0, 335.0),
    (2.5, 520.0, 12.0, [95e3, 99.9e3, 101e3, 103.5e3], [290.0, 295.0, 300.0, 310.0], 99.5e3, 103e3, 100.5e3,
     293.15, 305.0),
    (4.4, 480.0, 18.0, [30e3, 33e3, 120e3, 60e3], [280.0, 290.0, 340.0, 330.0], 31e3, 108e3, 36e3, 300.0, 360.0),
    (5.9, 450.0, 9.0, [60e3, 45e3, 47e3, 130e3], [330.0, 300.0, 300.0, 350.0], 46e3, 109e3, 48e3, 275.0, 320.0),
]


def pumpsim_at(kern, p, names, state):
    """pumpsim's cell geometry and outputs at a state (x built from the pressures)."""
    theta, omega, cur, pc, Tc, p_in, p_ex, pb, T_in, T_ex = state
    P = dict(zip(names, p))
    geo = {k: np.asarray(v).ravel() for k, v in zip(kern["cell_geometry"].name_out(), kern["cell_geometry"](theta, p))}
    R, g, T0 = P["gas.gas_constant"], P["gas.gamma"], P["gas.temperature"]
    m = np.asarray(pc) * geo["volume"] / (R * np.asarray(Tc))
    x = np.concatenate([[theta, omega, cur], m, m * R / (g - 1) * np.asarray(Tc),
                        [p_in * P["ports.inlet_volume"] / (R * T_in), p_ex * P["ports.exhaust_volume"] / (R * T_ex),
                         pb * P["booster.volume"] / (R * T0), p_in * P["ports.inlet_volume"] / (g - 1),
                         p_ex * P["ports.exhaust_volume"] / (g - 1), 0.0, 0.0]])
    out = {k: np.asarray(v).ravel() for k, v in zip(kern["pump_outputs"].name_out(), kern["pump_outputs"](x, p))}
    return geo, out


def independent_at(pump, table, state):
    """The same terms from the independent model."""
    theta, omega, cur, pc, Tc, p_in, p_ex, pb, T_in, T_ex = state
    pc, Tc, T0, N = np.asarray(pc), np.asarray(Tc), pump.T0, pump.N
    V, dV, _, a0, la = table(theta)
    v = M.Vanes(pump, theta)
    a_in = pump.cd_port * M.arc_overlaps(a0, la, *pump.inlet) * pump.inlet_width * pump.R
    a_ex = pump.cd_port * M.arc_overlaps(a0, la, *pump.exhaust) * pump.exhaust_width * pump.R
    a_lk = pump.cd_leak * (pump.tip_gap * pump.W + 2 * pump.end_gap * v.flank_out)
    o = lambda a, p1, t1, p2, t2: M.orifice(pump, a, p1, t1, p2, t2)  # noqa: E731
    open_in = min(max((pb - p_in - pump.check_crack) / pump.check_full, 0.0), 1.0)
    open_ex = min(max((p_ex - pump.p_atm - pump.valve_crack) / pump.valve_full, 0.0), 1.0)
    drive = pump.km * cur - pump.motor_friction * math.tanh(omega / M.TANH_SPEED) - pump.bearing
    dw, _, reac = M.mechanics(pump, v, omega, pc, p_ex, drive, [(1.0, 1.0)] * N)
    return {
        "volume": V, "dvolume": dV, "inlet_length": a_in / (pump.cd_port * pump.inlet_width),
        "exhaust_length": a_ex / (pump.cd_port * pump.exhaust_width), "exposed": v.flank_out,
        "inlet_flow": np.array([o(a_in[i], p_in, T_in, pc[i], Tc[i]) for i in range(N)]),
        "exhaust_flow": np.array([o(a_ex[i], pc[i], Tc[i], p_ex, T_ex) for i in range(N)]),
        "leak_flow": np.array([o(a_lk[i], pc[i - 1], Tc[i - 1], pc[i], Tc[i]) for i in range(N)]),
        "hose_flow": o(pump.cd_hose * pump.hose_area * open_in, pb, T0, p_in, T_in),
        "valve_flow": o(pump.cd_valve * pump.valve_area * open_ex, p_ex, T_ex, pump.p_atm, T0),
        "booster_leak": M.booster_leak_flow(pump, pb),
        "omegadot": dw, "normal": reac[:, 0], "slot1": reac[:, 1], "slot2": reac[:, 2],
    }


def compare(config=CONFIG, pocket_in_cell=False, states=STATES) -> dict:
    """term -> largest |independent - pumpsim| over the states, relative to the term's largest size."""
    cfg = load_config(config)
    kern, p = kernels(cfg), parameter_vector(cfg)
    from pumpsim.kernels.pneumatic import structure_of
    from pumpsim.model_spec.parameters import pneumatic_layout

    names = [q.name for q in pneumatic_layout(structure_of(cfg))]
    pump = replace(M.load(config), pocket_in_cell=pocket_in_cell)
    table = M.CellTable(pump, n=1024)
    worst, size = {}, {}
    for st in states:
        geo, out = pumpsim_at(kern, p, names, st)
        ref = {**out, **{k: geo[k] for k in ("volume", "dvolume", "exposed")}}
        for k, a in independent_at(pump, table, st).items():
            b = ref[k]
            worst[k] = max(worst.get(k, 0.0), float(np.max(np.abs(np.asarray(a) - b))))
            size[k] = max(size.get(k, 0.0), float(np.max(np.abs(b))))
    return {k: worst[k] / max(size[k], 1e-300) for k in worst}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--pocket-in-cell", action="store_true")
    a = ap.parse_args(argv)
    for k, v in compare(a.config, a.pocket_in_cell).items():
        print(f"{k:16s} {v:.2e}")


if __name__ == "__main__":
    main()
