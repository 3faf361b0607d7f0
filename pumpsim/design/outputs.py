"""Per-design outputs (spec §9) from one revolution of the constrained model at constant speed.

At constant speed Model 2 is exactly periodic in the rotor angle, so one revolution sampled
uniformly in angle *is* the periodic steady state, and a mean over it is a mean over time.

Definitions (i: vane, k: sample of the revolution):
- tip friction power  mean_k sum_i (mu_h(v_t) N v_t + c v_t^2)   (mu_h is odd: mu_h v_t >= 0)
- slot friction power mean_k sum_i mu_r(sdot) sdot (|F1| + |F2|)
  (spec §4: their sum equals the mean drive power tau * omega; tested)
- max_tip_pv          max (N / (w h)) |v_t| [Pa·m/s]: nominal contact pressure times slip speed,
                      the wear proxy. The pressure is the housing reaction over the tip's projected
                      area, axial width w (`rotor.width`) x vane thickness h -- the convention in
                      which sliding materials (carbon-graphite vanes) are rated for PV; the real
                      contact band of a rounded tip is narrower. NaN without rotor.width
- extension           s + L - l_m, the vane length standing out of the rotor
- lift_off            some housing reaction N < 0 (Model 2 holds the vane on the housing)
- paradox             some sample with no consistent slot contact-side set, or several that
                      differ (as `pumpsim simulate` reports it)
Each reduction also carries its derivative along given parameter directions (forward mode),
which the optimiser uses; a max/min takes the derivative at its arg-max (a subgradient).
"""
from __future__ import annotations

import math

import numpy as np

from ..tolerances import PARADOX_TOL

OUTPUTS = ("mean_torque", "rms_torque", "ptp_torque", "friction_power", "tip_friction_power",
           "slot_friction_power", "max_normal_force", "min_normal_force", "max_slot_force",
           "max_tip_pv", "min_extension", "max_extension", "lift_off", "paradox")
BOOL_OUTPUTS = ("lift_off", "paradox")
UNITS = {"mean_torque": "N·m", "rms_torque": "N·m", "ptp_torque": "N·m", "friction_power": "W",
         "tip_friction_power": "W", "slot_friction_power": "W", "max_normal_force": "N",
         "min_normal_force": "N", "max_slot_force": "N", "max_tip_pv": "Pa·m/s", "min_extension": "m",
         "max_extension": "m", "gas_power": "W", "pumping_speed": "m³/s", "mean_current": "A"}
# kernel outputs the reductions read
KERNEL_OUTPUTS = ("torque", "s", "sdot", "normal", "slot1", "slot2", "tip_slip", "mu_housing",
                  "mu_slot", "n_consistent", "ambiguity", "position_residual")
TANGENT_OUTPUTS = ("torque", "s", "sdot", "normal", "slot1", "slot2", "tip_slip", "mu_housing", "mu_slot")


def per_vane_name(i: int) -> str:
    return f"friction_power_{i}"


def _at(x, dx, idx):
    """Value of x at flat index idx and the tangents there (dx has a leading direction axis)."""
    v = x.ravel()[idx]
    return v, (None if dx is None else dx.reshape(dx.shape[0], -1)[:, idx])


def design_constants(values: dict, lm: float, width: float | None) -> dict:
    """The design's numbers the reductions need besides the kernel outputs: viscous tip
    coefficient, vane length L, slot mouth depth l_m and the tip's projected area w h (NaN
    without rotor.width)."""
    area = width * values["vane.thickness"] if width else math.nan
    return {"c_visc": values["effects.viscous_tip_friction"], "L": values["vane.length"], "lm": lm,
            "tip_area": area}


def reduce_revolution(a: dict, k: dict, da: dict | None = None,
                      dpar: dict | None = None, vanes: int | None = None) -> tuple[dict, dict]:
    """Outputs of one design from its revolution `a` (kernel outputs: torque (n,), per vane (N, n))
    and its constants k (design_constants). da: the same arrays' tangents with a leading axis of
    directions; dpar: tangents of k's entries along those directions. Returns (values,
    derivatives); derivatives is {} without da. vanes: as for reduce_batch (values only)."""
    out, at = _values(a, k, vanes)
    return out, ({} if da is None else _derivatives(a, k, da, dpar, out, at))


def _values(a: dict, k: dict, vanes=None) -> tuple[dict, dict]:
    """(outputs, where each extreme sits and the per-sample arrays the derivatives reuse): one
    design as a batch of one (the same arithmetic, hence the same bits, as in a batch)."""
    many, at = reduce_batch({nm: x[None] for nm, x in a.items()},
                            {nm: np.asarray([x], dtype=float) for nm, x in k.items()}, vanes)
    out = {nm: (bool(x[0]) if nm in BOOL_OUTPUTS else x[0]) for nm, x in many.items()}
    at = {nm: (x[0] if isinstance(x, np.ndarray) else x) for nm, x in at.items()}
    at["pv"] = a["normal"] * np.abs(a["tip_slip"]) / k["tip_area"]
    return out, at


def reduce_batch(a: dict, k: dict, vanes: int | None = None) -> tuple[dict, dict]:
    """The outputs of B designs at once: a holds the kernel outputs with a leading design axis
    (torque (B, n), per vane (B, N, n)), k the constants as (B,) arrays (design_constants).
    vanes: a's per-vane arrays hold one vane standing for that many alike ones (design.alike:
    the others are its samples shifted, so its extremes are theirs and its means each one's).
    Returns (output -> (B,) array, where each extreme sits)."""
    out = {}
    c_visc, L, lm, area = (np.asarray(k[nm], dtype=float)[:, None, None] for nm in ("c_visc", "L", "lm", "tip_area"))
    t = a["torque"]
    B = t.shape[0]
    rows = np.arange(B)

    def extreme(x, pick):
        """(value, flat index within the design's (N, n)) of x's max or min per design: the
        vane holding it, then the sample -- the first occurrence in flat order, as an arg-max of
        the flattened array gives it (NaN included), without copying a strided x to flatten it."""
        if x.shape[1] == 1:  # one vane (standing for alike ones): its own extreme
            k = pick(x[:, 0], axis=1)
            return x[rows, 0, k], k
        vane = pick((np.max if pick is np.argmax else np.min)(x, axis=2), axis=1)
        within = x[rows, vane]
        k = pick(within, axis=1)
        return within[rows, k], vane * x.shape[2] + k

    out["mean_torque"] = t.mean(axis=-1)
    out["rms_torque"] = np.sqrt(np.mean(t * t, axis=-1))
    hi, lo = np.argmax(t, axis=-1), np.argmin(t, axis=-1)
    out["ptp_torque"] = t[rows, hi] - t[rows, lo]
    N, v, mh = a["normal"], a["tip_slip"], a["mu_housing"]
    sd, F1, F2, mr = a["sdot"], a["slot1"], a["slot2"], a["mu_slot"]
    aF1, aF2, av = np.abs(F1), np.abs(F2), np.abs(v)
    tip = mh * N * v + c_visc * v * v
    slot = mr * sd * (aF1 + aF2)
    tip_v, slot_v = tip.mean(axis=-1), slot.mean(axis=-1)
    if vanes is not None and tip_v.shape[1] != vanes:
        tip_v, slot_v = np.repeat(tip_v, vanes, axis=1), np.repeat(slot_v, vanes, axis=1)
    out["tip_friction_power"] = tip_v.sum(axis=-1)
    out["slot_friction_power"] = slot_v.sum(axis=-1)
    out["friction_power"] = out["tip_friction_power"] + out["slot_friction_power"]
    per_vane = tip_v + slot_v
    for i in range(per_vane.shape[1]):
        out[per_vane_name(i)] = per_vane[:, i]
    out["max_normal_force"], iN_hi = extreme(N, np.argmax)
    out["min_normal_force"], iN_lo = extreme(N, np.argmin)
    F = np.maximum(aF1, aF2)
    out["max_slot_force"], iF = extreme(F, np.argmax)
    Nv, ipv = extreme(N * av, np.argmax)
    out["max_tip_pv"] = Nv / area[:, 0, 0]  # the pressure times slip speed where the product peaks
    ext = a["s"] + L - lm
    out["min_extension"], ie_lo = extreme(ext, np.argmin)
    out["max_extension"], ie_hi = extreme(ext, np.argmax)
    out["lift_off"] = out["min_normal_force"] < 0
    out["paradox"] = np.any(a["n_consistent"] < 0.5, axis=(1, 2)) | np.any(a["ambiguity"] > PARADOX_TOL, axis=(1, 2))
    at = dict(hi=hi, lo=lo, iN_hi=iN_hi, iN_lo=iN_lo, F=F, iF=iF, ipv=ipv, ext=ext,
              ie_lo=ie_lo, ie_hi=ie_hi, vanes=per_vane.shape[1])
    return out, at


def _derivatives(a: dict, k: dict, da: dict, dpar: dict, out: dict, at: dict) -> dict:
    """Tangents of the outputs along da's directions (the extremes at the samples _values found)."""
    der = {}
    c_visc, area = k["c_visc"], k["tip_area"]
    t, dt = a["torque"], da["torque"]
    der["mean_torque"] = dt.mean(axis=1)
    der["rms_torque"] = (dt * t).mean(axis=1) / out["rms_torque"]
    der["ptp_torque"] = dt[:, at["hi"]] - dt[:, at["lo"]]
    N, v, mh = a["normal"], a["tip_slip"], a["mu_housing"]
    sd, F1, F2, mr = a["sdot"], a["slot1"], a["slot2"], a["mu_slot"]
    dN, dv, dmh = da["normal"], da["tip_slip"], da["mu_housing"]
    dsd, dF1, dF2, dmr = da["sdot"], da["slot1"], da["slot2"], da["mu_slot"]
    dc = dpar["c_visc"][:, None, None]
    dtip = dmh * N * v + mh * dN * v + mh * N * dv + dc * v * v + 2 * c_visc * v * dv
    dslot = (dmr * sd * (np.abs(F1) + np.abs(F2)) + mr * dsd * (np.abs(F1) + np.abs(F2))
             + mr * sd * (np.sign(F1) * dF1 + np.sign(F2) * dF2))
    dtip_v, dslot_v = dtip.mean(axis=2), dslot.mean(axis=2)
    der["tip_friction_power"] = dtip_v.sum(axis=1)
    der["slot_friction_power"] = dslot_v.sum(axis=1)
    der["friction_power"] = der["tip_friction_power"] + der["slot_friction_power"]
    for i in range(at["vanes"]):
        der[per_vane_name(i)] = dtip_v[:, i] + dslot_v[:, i]
    der["max_normal_force"] = _at(N, dN, at["iN_hi"])[1]
    der["min_normal_force"] = _at(N, dN, at["iN_lo"])[1]
    dF = np.where(np.abs(F1) >= np.abs(F2), np.sign(F1) * dF1, np.sign(F2) * dF2)
    der["max_slot_force"] = _at(at["F"], dF, at["iF"])[1]
    pv = at["pv"]
    dpv = (dN * np.abs(v) + N * np.sign(v) * dv) / area - pv * (dpar["tip_area"] / area)[:, None, None]
    der["max_tip_pv"] = _at(pv, dpv, at["ipv"])[1]
    dext = da["s"] + (dpar["L"] - dpar["lm"])[:, None, None]
    der["min_extension"] = _at(at["ext"], dext, at["ie_lo"])[1]
    der["max_extension"] = _at(at["ext"], dext, at["ie_hi"])[1]
    return der
