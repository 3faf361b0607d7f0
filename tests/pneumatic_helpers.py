"""Pneumatic test configurations (spec §8) built from the bundled examples."""
from __future__ import annotations

import math

from pumpsim.config import config_from_dict
from tests.conftest import apply_changes, example_dict

GAS_TABLES = {
    "rotor.width": 0.02,
    "ports": {"inlet": [0.3, 2.0], "exhaust": [3.5, 5.5], "width": 0.01},
    "booster": {"volume": 4e-3},
}


def gas_config(base="ellipse_4vanes", **changes):
    d = apply_changes(example_dict(base), GAS_TABLES)
    d = apply_changes(d, changes)
    return config_from_dict(d)


def ellipse_radius(alpha, a, b, psi, harmonics):
    """Polar radius about the housing centre (spec §1), written independently of codegen."""
    r = a * b / math.sqrt((b * math.cos(alpha - psi)) ** 2 + (a * math.sin(alpha - psi)) ** 2)
    return r + sum(A * math.cos(k * (alpha - psi - g)) for k, A, g in harmonics)


def evp_config(**changes):
    """The bundled EVP example with dotted-key changes (config dict level)."""
    return config_from_dict(apply_changes(example_dict("evp_booster"), changes))


def speed_config(speed=300.0, **changes):
    """The EVP example at constant speed (operation.mode = "speed")."""
    return evp_config(**{"operation.mode": "speed", "operation.speed": speed, **changes})


# an ideal pump for the closed forms: no leaks, big ideal check valves, isothermal cells, windows
# closing at the largest (inlet) and smallest (exhaust) cell, ports as wide as the rotor
IDEAL = {
    "leak.tip_gap": 0.0, "leak.end_gap": 0.0, "booster.leak": 0.0,
    "ports.inlet": [-3 * math.pi / 4, -math.pi / 4], "ports.exhaust": [math.pi / 4, 3 * math.pi / 4],
    "ports.inlet_width": 0.025, "ports.exhaust_width": 0.025, "ports.discharge_coefficient": 1.0,
    "ports.hose_diameter": 0.03, "ports.check_cracking": 0.0, "ports.check_full_open": 1.0,
    "ports.inlet_volume": 1e-8,
    "valve.area": 1e-3, "valve.cracking": 0.0, "valve.full_open": 1.0,
    "gas.heat_transfer": 3e5,
}
