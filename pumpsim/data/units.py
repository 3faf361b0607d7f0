"""Units of measured signals: the factor of each known unit to SI, and units in column headers
('torque [N*mm]')."""
from __future__ import annotations

import math
import re

from ..errors import DataError

# Units as the factor to SI. Keys are normalised (see `unit_key`): lower case, without spaces and the
# separators * . · between unit symbols, so 'N*mm', 'N.mm', 'N·mm' and 'Nmm' are one unit.
TORQUE_UNITS = {"nm": 1.0, "nmm": 1e-3, "mnm": 1e-3, "ncm": 1e-2}
SPEED_UNITS = {"rad/s": 1.0, "rpm": 2 * math.pi / 60, "1/min": 2 * math.pi / 60, "min^-1": 2 * math.pi / 60,
               "min-1": 2 * math.pi / 60, "u/min": 2 * math.pi / 60, "rev/min": 2 * math.pi / 60,
               "r/min": 2 * math.pi / 60, "rev/s": 2 * math.pi, "hz": 2 * math.pi, "deg/s": math.pi / 180}
TIME_UNITS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6, "\u03bcs": 1e-6}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180, "\u00b0": math.pi / 180}
UNITS = {"time": TIME_UNITS, "torque": TORQUE_UNITS, "speed": SPEED_UNITS, "angle": ANGLE_UNITS}
UNIT_NAMES = {"time": "s, ms, us", "torque": "N*m, N*mm, mN*m, N*cm",
              "speed": "rad/s, rpm (1/min, U/min), rev/s (Hz), deg/s", "angle": "rad, deg"}
SI_UNIT = {"time": "s", "torque": "N*m", "speed": "rad/s", "angle": "rad"}


def unit_key(unit: str) -> str:
    """'N*mm', 'N.mm', 'N\u00b7mm', ' Nmm ' -> 'nmm'; 'min\u207b\u00b9' -> 'min^-1'."""
    u = unit.strip().lower().replace("\u207b\u00b9", "^-1").replace("\u00b9", "")
    return re.sub(r"[\s*.\u00b7\u22c5\u2219]", "", u)


def unit_factor(quantity: str, unit: str, where: str = "") -> float:
    """Factor from `unit` to SI for `quantity` (time, torque, speed, angle); DataError naming the
    known units otherwise."""
    f = UNITS[quantity].get(unit_key(unit))
    if f is None:
        raise DataError(f"{where}{quantity} unit must be one of {UNIT_NAMES[quantity]}, got '{unit}'")
    return f


_ANNOTATION = re.compile(r"^(?P<name>.*?)\s*(?:\[(?P<u1>[^\]]*)\]|\((?P<u2>[^)]*)\)|/\s*(?P<u3>[^/\s]+))$")


def split_header(text: str):
    """'torque [N*mm]' / 'torque (N*mm)' -> ('torque', 'N*mm'); 'torque' -> ('torque', None)."""
    m = _ANNOTATION.match(text.strip())
    if m and m.group("name"):
        return m.group("name").strip(), next(u for u in (m.group("u1"), m.group("u2"), m.group("u3"))
                                           if u is not None).strip()
    return text.strip(), None
