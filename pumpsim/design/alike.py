"""Designs whose vanes are alike: one vane's revolution gives every vane's.

In Model 2 at constant speed each vane moves on its own (the vanes share only the rotor's torque
sum), and vane k, whose slot sits 2 pi k / N ahead of vane 0's, is at rotor angle theta where vane 0
is at theta + 2 pi k / N. So when a design's vanes are alike (every per-vane friction factor
equal) and its revolution's n samples are uniform with N dividing n, vane k's samples are vane
0's shifted by k n / N: one vane is evaluated instead of N, and the reductions read one vane.

The one vane runs on the SIMD library of the 1-vane variant with the same housing and laws: its
vane body is the N-vane library's instruction for instruction (vane 0's outputs equal bit for
bit: tested), and the rotor torque is the shifted shares summed as the library sums them.

Numbers: vane k's samples are those of the same physical state reached from an angle rounded
another way (theta_j + 2 pi k / N in the N-vane kernel, theta_(j + k n / N) here), so they agree
with the N-vane kernel's within its rounding: observed <= 5e-12 of each output's scale on the
concentric test rig, whose position solve is the least well conditioned; tests hold SIMD_REL.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..model_spec import outputs as kernel_outputs
from ..model_spec.parameters import layout_names

class OneVane:
    """The 1-vane variant's SIMD library and where its parameters sit in the N-vane vector."""

    def __init__(self, structure, fast):
        self.structure, self.fast, self.vanes = structure, fast, structure.vanes
        names = layout_names(structure)
        one = layout_names(dataclasses.replace(structure, vanes=1))
        if not set(one) <= set(names):  # a per-vane parameter other than the friction factor
            raise ValueError(f"{structure.variant}: the 1-vane layout has {sorted(set(one) - set(names))}")
        self.columns = np.array([names.index(nm) for nm in one])
        self.factors = np.array([names.index(f"effects.vane_friction_factor.{k}") for k in range(self.vanes)])
        self.bearing = names.index("operation.bearing_torque")

    def alike(self, P, n: int) -> np.ndarray:
        """(designs,) bool: the designs (rows of P) whose vanes one vane stands for, at n samples."""
        if n % self.vanes:
            return np.zeros(len(P), bool)
        F = P[:, self.factors]
        return np.all(F == F[:, :1], axis=1)

    def evaluate(self, P, theta, omega, outputs) -> dict:
        """evaluate.evaluate_designs for designs all alike at constant speed (omegadot 0) on
        uniform revolutions theta ((n,) or (D, n)): the torque (D, n) and vane 0's outputs as
        (D, 1, n)."""
        D, n = len(P), theta.shape[-1]
        th = np.ascontiguousarray(np.broadcast_to(theta, (D, n))).reshape(-1)
        wanted = [nm for nm in outputs if nm != "torque"]
        if "torque_share" not in wanted:
            wanted.append("torque_share")
        res = self.fast(th, np.repeat(omega, n), 0.0, np.ascontiguousarray(P[:, self.columns]), block=n,
                        outputs=wanted)
        share = res["torque_share"].reshape(D, n)
        step = n // self.vanes
        total = share.copy()
        for k in range(1, self.vanes):  # the library's order: ((s0 + s1) + s2) + ...
            total += np.roll(share, -k * step, axis=1)
        torque = P[:, self.bearing][:, None] + total  # rotor.inertia x omegadot is 0 here
        out = {nm: res[nm].reshape(D, 1, n) for nm in outputs
               if nm != "torque" and kernel_outputs.shape(nm) != "sample"}
        out["torque"] = torque
        return out


def spread(ev: dict, vanes: int, n: int) -> dict:
    """The N-vane arrays (D, N, n) from one vane's (D, 1, n): vane k is vane 0 shifted by k n / N."""
    step = n // vanes
    return {nm: (a if a.ndim == 2 else np.concatenate([np.roll(a, -k * step, axis=2) for k in range(vanes)], axis=1))
            for nm, a in ev.items()}


__all__ = ["OneVane", "spread"]
