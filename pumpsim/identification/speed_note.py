"""What a fit owes to a speed it did not measure: data without a speed column, the speed not
fitted, so the model turns at the config's operation.speed and every estimate rests on it."""
from __future__ import annotations

import math

import numpy as np

from .identifiability import to_fix
from .problem import ConstantSpeedProblem, base_name


def configured_speed_note(cfg, data, result, ripple_order=1) -> str | None:
    """The note for one constant-speed measurement without a speed column (None otherwise): the
    speed it assumed, how far a 1 % error in that speed moves mu, and what removes the dependence.
    The shift is the least-squares one at the fit, dx = -(J'J)^-1 J' j_speed d_speed (J: the
    fitted names' columns, j_speed the speed's): a concentric rig, whose torque is mu times the
    vanes' centrifugal load m r omega^2, gives -2 % per +1 %."""
    names = [n for n, e in result.estimates.items() if e.identifiable and e.value is not None]
    if data.speed is not None or cfg.mode != "speed" or not cfg.speed or "mu" not in names \
            or any(base_name(n) == "speed" for n in result.estimates):
        return None
    values = {n: result.estimates[n].value for n in names}
    prob = ConstantSpeedProblem(cfg, data, names + ["speed"], {**values, "speed": cfg.speed}, None, ripple_order)
    m, J = prob.model_and_jacobian(prob.x0)
    dx = np.linalg.lstsq(J[:, :-1], J[:, -1], rcond=None)[0]  # d(fitted)/d(speed) holding the fit
    mu = values["mu"]
    per_percent = -dx[names.index("mu")] * 0.01 * cfg.speed / mu * 100
    dead, flat = to_fix(prob.names, J, prob.x0, m)
    cure = ("a speed column removes it (this data cannot tell the speed from mu: the torque depends on "
            "their combination only)" if "speed" in dead + flat else
            "a speed column, or fitting the speed too ('speed' in params: --params mu,speed), removes it")
    return (f"speed: the data has no speed column and the speed was not fitted, so the model turns at the "
            f"config's operation.speed {cfg.speed:.6g} rad/s ({cfg.speed * 30 / math.pi:.6g} rpm); a 1 % error "
            f"in it moves mu by {per_percent:+.2g} % ({per_percent * mu / 100:+.2g}); {cure}")


def speed_notes(cfg, datasets, result) -> list:
    """[configured_speed_note] for a converged fit of one measurement, else []."""
    note = configured_speed_note(cfg, datasets[0], result) if len(datasets) == 1 and result.converged else None
    return [note] if note else []
