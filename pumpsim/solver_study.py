"""Solver study for the contact model (report §7-8, Tables 7 and 13) on our model.

At constant speed from an in-contact start, each row integrates the contact model with one setting
(tolerance and maximum step, contact stiffness or law, BDF or explicit Runge-Kutta) and reports
steps, failed steps, right-hand-side evaluations, wall time and the largest deviation from Model 2
over the last revolution (torque relative to its RMS, housing normal force relative to its RMS).
"""
from __future__ import annotations

import copy
import dataclasses
import json
import math

import numpy as np

from .io import write_text
from .tolerances import SOLVER_STUDY_ATOL, SOLVER_STUDY_RTOL

REPORT_NONLINEAR_P1 = 5.0e4 / (1.0e-3) ** 4  # report §8.1


def default_rows(cfg):
    """The study's settings; with the gas tables only those the gas model takes (CVODES at its own
    steps: no maximum step, no explicit Runge-Kutta)."""
    law = cfg.contact_laws["housing"]
    k = cfg.values["contact.housing.stiffness"]
    rows = [
        {"name": f"BDF rtol 1e-4 ({law}, k {k:g})", "method": "cvodes", "rtol": 1e-4},
        {"name": f"BDF rtol 1e-6 ({law}, k {k:g})", "method": "cvodes", "rtol": 1e-6},
        {"name": f"BDF rtol 1e-8 ({law}, k {k:g})", "method": "cvodes", "rtol": 1e-8},
        {"name": "BDF rtol 1e-6, max step 1e-5 s", "method": "cvodes", "rtol": 1e-6, "max_step": 1e-5},
        {"name": "BDF, linear k 1e5 c 15 (report case 1)", "method": "cvodes", "rtol": 1e-6,
         "contact": {"law": "linear", "stiffness": 1e5, "damping": 15.0}},
        {"name": "BDF, linear k 5e4 c 15 (report case 2)", "method": "cvodes", "rtol": 1e-6,
         "contact": {"law": "linear", "stiffness": 5e4, "damping": 15.0}},
        {"name": "BDF, report nonlinear (case 3)", "method": "cvodes", "rtol": 1e-6,
         "contact": {"law": "report-nonlinear", "stiffness": REPORT_NONLINEAR_P1}},
        {"name": "explicit RK4, step 1e-6 s", "method": "rk", "max_step": 1e-6},
    ]
    if cfg.pneumatic is not None:
        rows = [r for r in rows if "max_step" not in r and r.get("method", "cvodes") == "cvodes"]
    return rows


def _with_contact(cfg, contact):
    if not contact:
        return cfg
    c = dataclasses.replace(cfg, values=dict(cfg.values), contact_laws=dict(cfg.contact_laws))
    c.contact_laws["housing"] = contact["law"]
    c.values["contact.housing.stiffness"] = contact["stiffness"]
    c.values["contact.housing.damping"] = contact.get("damping", 0.0)
    return c


def solver_study(cfg, revolutions=10.0, per_revolution=360, speed=None, rows=None, log=None):
    from .simulate import simulate

    speed = speed or (cfg.speed if cfg.mode == "speed" and cfg.speed else 471.0)
    base = dataclasses.replace(cfg, mode="speed", speed=speed, values=copy.deepcopy(cfg.values))
    T = 2 * math.pi / speed
    duration, rate = revolutions * T, per_revolution / T
    ref = simulate(base, duration=duration, rate=rate)
    last = slice(-per_revolution, None)
    rms_t = float(np.sqrt(np.mean(ref.torque[last] ** 2)))
    rms_n = float(np.sqrt(np.mean(ref.vanes["normal"][:, last] ** 2)))
    out = []
    for row in rows or default_rows(base):
        c = _with_contact(base, row.get("contact"))
        res = simulate(c, model="contact", duration=duration, rate=rate, initial="housing",
                       method=row.get("method", "cvodes"), rtol=row.get("rtol", SOLVER_STUDY_RTOL),
                       atol=row.get("atol", SOLVER_STUDY_ATOL), max_step=row.get("max_step"))
        st = res.stats
        entry = {
            "name": row["name"], "method": row.get("method", "cvodes"),
            "steps": st.get("nsteps", 0), "failed_steps": st.get("netfails", 0),
            "rhs_evaluations": st.get("nfevals", 0), "jacobian_evaluations": st.get("njevals", 0),
            "newton_iterations": st.get("nniters", 0),
            "wall_time": st["wall_time"], "events": st.get("events", 0),
            "torque_deviation": float(np.max(np.abs(res.torque[last] - ref.torque[last])) / rms_t),
            "normal_deviation": float(np.max(np.abs(res.vanes["normal"][:, last]
                                                     - ref.vanes["normal"][:, last])) / rms_n),
        }
        out.append(entry)
        if log:
            log(format_row(entry))
    return {"speed": speed, "revolutions": revolutions, "rows": out}


HEADER = (f"{'setting':<44}{'steps':>9}{'failed':>8}{'rhs evals':>11}{'jac evals':>11}{'wall [s]':>10}"
          f"{'max dev torque':>16}{'max dev N':>11}")


def format_row(e):
    return (f"{e['name']:<44}{e['steps']:>9}{e['failed_steps']:>8}{e['rhs_evaluations']:>11}{e['jacobian_evaluations']:>11}"
            f"{e['wall_time']:>10.3f}{e['torque_deviation']:>16.3%}{e['normal_deviation']:>11.3%}")


def write_json(path, result):
    write_text(path, json.dumps(result, indent=1))
