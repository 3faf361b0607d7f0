"""Designs through the SIMD library's reduction entry (codegen/simd_reduce.py): each design's
revolution is reduced in cache to outputs.reduce_batch's numbers -- the same operations, hence the
same bits (tested) -- so no (designs, outputs, samples) array is made and no NumPy pass runs over
one. Where the library has no such entry the kernel's outputs go through reduce_batch."""
from __future__ import annotations

import numpy as np

from ..tolerances import PARADOX_TOL, POSITION_TOL
from .outputs import per_vane_name

_SCALARS = ("mean_torque", "rms_torque", "ptp_torque", "tip_friction_power", "slot_friction_power", "friction_power")
_EXTREMES = ("max_normal_force", "min_normal_force", "max_slot_force")


def fused_outputs(fast, P, theta, omega, const: dict, alike: int = 1) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """(out, res_ok, s_min, s_max) of D designs: P (D, n_p) the library's parameter vectors,
    theta (n,) their shared revolution, omega (D,), const as reduce_batch's plus "bearing" (the
    bearing torque, read when alike > 1: one vane standing for `alike`). out: reduce_batch's
    outputs (D,) in its order; res_ok: every position residual finite and within POSITION_TOL;
    s_min, s_max: the vane extension's extremes (screen.vanes_ok's tests)."""
    D = len(P)
    consts = np.column_stack([np.broadcast_to(np.asarray(const[k], dtype=float), (D,))
                              for k in ("c_visc", "L", "lm", "bearing")])
    R = fast.reduce_designs(theta, omega, P, consts, (POSITION_TOL, PARADOX_TOL), alike)
    names = fast.manifest["reductions"]["columns"]
    c = {nm: R[:, i] for i, nm in enumerate(names)}
    out = {nm: c[nm] for nm in _SCALARS}
    for i in range(R.shape[1] - len(names)):
        out[per_vane_name(i)] = R[:, len(names) + i]
    out.update({nm: c[nm] for nm in _EXTREMES})
    out["max_tip_pv"] = c["max_tip_pv_force_speed"] / np.asarray(const["tip_area"], dtype=float)
    out["min_extension"], out["max_extension"] = c["min_extension"], c["max_extension"]
    out["lift_off"] = out["min_normal_force"] < 0
    out["paradox"] = c["paradox"] != 0
    return out, c["positions_converged"] != 0, c["min_s"], c["max_s"]


__all__ = ["fused_outputs"]
