"""The pump-down's printed and reported work split closes: shaft work = its parts, with valve
damping (reed) and contact work (Model 1) named, not folded into the kinetic energy."""
import re

import numpy as np
import pytest

from pumpsim.report.pumpdown import work_row
from pumpsim.pneumatics.pumpdown import PumpdownResult
from tests.tolerances import ROUNDING_REL

SUMMARY = {"time_to_target": None, "final_pressure": 9e4, "start_pressure": 101300.0, "target_pressure": 3e4,
           "peak_current": 50.0, "mean_current": 10.0, "energy": 20.0, "mean_speed_rpm": 4000.0,
           "shaft_work": 10.0, "gas_work": 4.0, "friction_work": 3.0, "valve_damping_work": 1.0,
           "contact_work": 0.5, "solver": {"nsteps": 1, "nfevals": 1, "njevals": 1, "netfails": 0,
                                           "wall_time": 0.1}}


def _numbers(text):
    return [float(x) for x in re.findall(r"\d+(?:\.\d+)?", text)]


def test_printed_work_split_names_every_part_and_closes():
    line = PumpdownResult("evp", np.zeros(2), {}, SUMMARY).text().splitlines()[2]
    assert "valve damping 1 J" in line and "contacts 0.5 J" in line and "kinetic 1.5 J" in line
    shaft, *parts = _numbers(line)
    assert sum(parts) == pytest.approx(shaft, rel=ROUNDING_REL)


def test_report_work_row_closes():
    label, value = work_row(SUMMARY)
    assert label == "shaft work = gas + friction + valve damping + contacts + kinetic"
    shaft, *parts = _numbers(value)
    assert sum(parts) == pytest.approx(shaft, rel=ROUNDING_REL)


def test_the_energy_figures_bars_add_up_to_the_supplys_energy():
    """The bars under 'Where the ... J from the supply go': every part of the shaft work but its
    kinetic share, the motor's losses, and the kinetic energy left (rotor, vanes, motor) as the
    rest; without a motor they add up to the shaft work."""
    from pumpsim.report.pumpdown import energy_parts

    s = {**SUMMARY, "copper_loss": 6.0, "motor_friction_work": 1.5}
    parts = dict(energy_parts(s))
    assert sum(parts.values()) == pytest.approx(s["energy"], rel=ROUNDING_REL)
    assert parts["kinetic (rotor, vanes, motor)"] == pytest.approx(20.0 - 6.0 - 1.5 - 8.5, rel=ROUNDING_REL)
    speed_driven = dict(energy_parts({**s, "energy": None}))
    assert sum(speed_driven.values()) == pytest.approx(s["shaft_work"], rel=ROUNDING_REL)
