"""Evaluate designs: config -> parameter vector -> one revolution of inverse dynamics -> outputs.

`evaluate_designs(kern, P, theta, omega)` calls the compiled kernel for a batch of designs (P: one
parameter vector per design) on every vane; designs whose vanes are alike go through one vane
instead (`one_vane`, alike.py; `revolutions` picks per design). Everything else (admissibility,
reductions, status) is NumPy on their results. Kernels are loaded by whoever calls this -- a Dask worker loads or
builds its own from the hashed cache; compiled functions never travel between processes.
"""
from __future__ import annotations

import dataclasses
import math
import os
import threading

import numpy as np

from .. import interrupt
from ..config import as_array, config_from_dict
from ..errors import ConfigError, PumpsimError
from ..geometry import POSITION_TOL, geometry_verdict, mouth_depth, slot_room
from ..kernels import load_kernels
from ..model_spec import outputs as kernel_outputs
from ..tolerances import CONTACT_PERIODIC_REL
from .pneumatic import gas_outputs, motor_driven
from .outputs import (BOOL_OUTPUTS, KERNEL_OUTPUTS, TANGENT_OUTPUTS, design_constants, per_vane_name, reduce_batch,
                      reduce_revolution)
from .study import SPEED_KEY, get_value
from .alike import OneVane, spread
from .fused import fused_outputs
from .screen import ellipse_clear, extension_ok, housing_samples, polygon_clear, position_checks
from .vector import design_maps, mouth_depths
from .columns import Block, rows, table_columns
from .store import columns, columns_to_table, max_vanes, rows_to_table


def _per_sample(name: str) -> bool:
    """One value per sample (not per vane): the contract's declared shape decides, not this module."""
    return kernel_outputs.shape(name) == "sample"


class _Maps(threading.local):
    """Per-thread cache of kernel maps over one revolution with the speed and p shared (CasADi
    copies a shared input once per call instead of once per sample)."""

    def __init__(self):
        self.cache = {}
        self.buffers = {}

    def get(self, kern, name, n, shared):
        key = (kern.key, name, n, shared)
        if key not in self.cache:
            f = kern[name] if name != "fwd_inverse_dynamics" else kern["inverse_dynamics"].forward(1)
            self.cache[key] = f.map(f"{f.name()}_rev{n}", "serial", n, list(shared), [])
        return self.cache[key]

    def buffered(self, kern, name, n, shared, outputs):
        """The map evaluated in place on NumPy buffers (Function.buffer: no DM conversions, which
        cost more than the kernel). Returns (inputs, outputs by name, evaluate)."""
        key = (kern.key, name, n, shared, tuple(outputs))
        if key not in self.buffers:
            f = self.get(kern, name, n, shared)
            buf, run = f.buffer()
            args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
            for i, a in enumerate(args):
                buf.set_arg(i, memoryview(a))
            res = {}
            for i, nm in enumerate(f.name_out()):
                if nm in outputs:
                    res[nm] = np.zeros(f.nnz_out(i))
                    buf.set_res(i, memoryview(res[nm]))
            self.buffers[key] = (args, res, run, buf)
        return self.buffers[key][:3]


_MAPS = _Maps()


def revolution(angle0: float, n: int) -> np.ndarray:
    return angle0 + 2 * math.pi * np.arange(n) / n


def _split(names, res, N, keep):
    out = {}
    for i, nm in enumerate(names):
        if nm in keep:
            a = np.asarray(res[i])
            out[nm] = a.ravel() if _per_sample(nm) else a.reshape(N, -1, order="F")
    return out


def fast_kernel(structure):
    """The SIMD inverse dynamics (pumpsim.kernels.simd) of a variant, or None where it cannot be
    built (then the scalar CasADi kernel runs). PUMPSIM_DESIGN_KERNEL=scalar forces the latter."""
    if os.environ.get("PUMPSIM_DESIGN_KERNEL", "") == "scalar":
        return None
    key = ("fast", structure)
    if key not in _MAPS.cache:
        from ..kernels import load_fast_kernel

        try:
            fk = load_fast_kernel(structure, fallback=True)
        except PumpsimError:
            fk = None
        _MAPS.cache[key] = fk if fk is not None and fk.simd else None
    return _MAPS.cache[key]


_ONE: dict = {}  # structure -> OneVane


def one_vane(structure):
    """alike.OneVane of an N-vane constrained structure (N > 1), or None where no 1-vane SIMD
    library can be had (then every vane is evaluated). The library is looked up each time:
    PUMPSIM_DESIGN_KERNEL=scalar may have been set since."""
    fast = fast_kernel(dataclasses.replace(structure, vanes=1)) if structure.vanes > 1 else None
    if fast is None:
        return None
    if structure not in _ONE or (_ONE[structure] is not None and _ONE[structure].fast is not fast):
        try:
            _ONE[structure] = OneVane(structure, fast)
        except ValueError:  # vanes that are not copies of one another in the parameters: every vane
            _ONE[structure] = None
    return _ONE[structure]


def evaluate_designs(kern, P, theta, omega, outputs=KERNEL_OUTPUTS) -> dict:
    """Inverse dynamics at constant speed for a batch of designs of one compiled variant.
    P: (designs, len(p)); theta: (n,) rotor angles shared by all designs, or (designs, n);
    omega: (designs,). Returns name -> (designs, n) for the torque and (designs, N, n) per vane.

    On the SIMD library the batch is one call with one block of samples per design: the library
    restarts its lanes at every block, so a design's numbers never depend on which designs share
    its batch (bit for bit, tests). Else one scalar-kernel call per design on NumPy buffers."""
    P = np.atleast_2d(np.asarray(P, dtype=float))
    theta = np.asarray(theta, dtype=float)
    D, n, N = P.shape[0], theta.shape[-1], kern.structure.vanes
    omega = np.broadcast_to(np.asarray(omega, dtype=float), (D,))
    fast = fast_kernel(kern.structure)
    if fast is not None:
        th = np.ascontiguousarray(np.broadcast_to(theta, (D, n))).reshape(-1)
        res = fast(th, np.repeat(omega, n), 0.0, np.ascontiguousarray(P), block=n)
        return {nm: (res[nm].reshape(D, n) if _per_sample(nm) else
                     res[nm].reshape(N, D, n).transpose(1, 0, 2)) for nm in outputs}
    out = {nm: np.empty((D, n) if _per_sample(nm) else (D, N, n)) for nm in outputs}
    args, res, run = _MAPS.buffered(kern, "inverse_dynamics", n, (1, 2, 3), outputs)
    args[2][0] = 0.0
    for d in range(D):
        args[0][:] = theta if theta.ndim == 1 else theta[d]
        args[1][0] = omega[d]
        args[3][:] = P[d]
        run()
        for nm in outputs:
            # per-vane outputs come vane-major within each sample: (n, N) in C order
            out[nm][d] = res[nm] if _per_sample(nm) else res[nm].reshape(n, N).T
    return out


def kernel_tangents(kern, p, theta, omega, dP, domega) -> dict:
    """Directional derivatives of the kernel outputs along k directions (dP (k, len(p)) in p,
    domega (k,) in the speed) by the compiled forward-mode AD. Returns name -> (k, ...)."""
    n, N = theta.size, kern.structure.vanes
    f = kern["inverse_dynamics"]
    names = f.name_out()
    nom = _MAPS.get(kern, "inverse_dynamics", n, (1, 2, 3))(theta[None, :], omega, 0.0, p[:, None])
    nom = nom if isinstance(nom, (list, tuple)) else [nom]
    # inputs: theta, omega, omegadot, p, the nominal outputs, then their seeds (theta's is 0)
    k_in = 4 + len(names)
    fw = _MAPS.get(kern, "fwd_inverse_dynamics", n, (1, 2, 3, k_in, k_in + 1, k_in + 2, k_in + 3))
    out = {nm: [] for nm in TANGENT_OUTPUTS}
    for j in range(dP.shape[0]):
        r = fw(theta[None, :], omega, 0.0, p[:, None], *nom, 0.0, domega[j], 0.0, dP[j][:, None])
        one = _split(names, r, N, TANGENT_OUTPUTS)
        for nm in TANGENT_OUTPUTS:
            out[nm].append(one[nm])
    return {nm: np.array(v) for nm, v in out.items()}


def housing_check_samples(kern, p, n):
    args, res, run = _MAPS.buffered(kern, "housing_curve", n, (1,), ("point", "curvature"))
    alpha = np.linspace(-math.pi, math.pi, n, endpoint=False)
    args[0][:] = alpha
    args[1][:] = p
    run()
    return alpha, res["point"].reshape(n, 2).T.copy(), res["curvature"].copy()


HOUSING_CHUNK = 8  # designs per housing-curve call (a last short chunk wastes at most 7)


def housing_batch(kern, P, n):
    """housing_check_samples of B designs in one call: (alpha (n,), points (B, 2, n), curvature
    (B, n)); the same per-sample function, hence the same numbers, as one design at a time."""
    B, size = len(P), HOUSING_CHUNK  # one map size: a CasADi map takes ~0.1 s to make
    args, res, run = _MAPS.buffered(kern, "housing_curve", n * size, (), ("point", "curvature"))
    alpha = np.linspace(-math.pi, math.pi, n, endpoint=False)
    args[0][:] = np.tile(alpha, size)
    pts, curv = np.empty((B, 2, n)), np.empty((B, n))
    for lo in range(0, B, size):
        k = min(size, B - lo)
        args[1].reshape(size, n, -1)[:k] = P[lo:lo + k, None, :]
        run()
        pts[lo:lo + k] = res["point"].reshape(size, n, 2)[:k].transpose(0, 2, 1)
        curv[lo:lo + k] = res["curvature"].reshape(size, n)[:k]
    return alpha, pts, curv


class Prepared:
    """One design: its validated config and parameter vector, or why it has none."""

    __slots__ = ("cfg", "p", "status", "values", "width")

    def __init__(self, cfg=None, p=None, status="ok", values=None, width=None):
        self.cfg, self.p, self.status, self.values, self.width = cfg, p, status, values, width

    def constants(self) -> dict:
        """What the reductions need besides the kernel outputs (outputs.design_constants)."""
        return design_constants(self.values, mouth_depth(self.values), self.width)


def prepare(study, values: dict) -> Prepared:
    try:
        table = study.design_dict(values)
        cfg = config_from_dict(table)
        pv = cfg.parameters("constrained")
        return Prepared(cfg, as_array(pv), "ok", pv.values, get_value(table, "rotor.width"))
    except ConfigError as e:
        return Prepared(status=f"config: {e}")
    except (TypeError, ValueError, OverflowError) as e:  # e.g. a non-finite sampled value
        return Prepared(status=f"config: {type(e).__name__}: {e}")


def design_speeds(study, cfg) -> list:
    """The speeds a design is evaluated at; NaN where its motor sets the speed (pneumatic.py)."""
    if study.speeds:
        return list(study.speeds)
    return [math.nan] if motor_driven(study, cfg) else [float(cfg.speed)]


def _gas_points(study, pr, speeds, theta) -> tuple[list, dict, dict | None]:
    """(speeds, {speed: gas outputs}, the kernel outputs over the revolution theta per speed,
    stacked as the mechanical kernel's) from the gas model's periodic steady state
    (pneumatic.py): a config with the gas tables is studied pumping, its outputs carry the gas
    loads. ({}, None for a config without them.) Under a motor the one speed is the motor's."""
    if study.booster_pressure is None:
        return speeds, {}, None
    runs = ([gas_outputs(pr.cfg, study.booster_pressure, None, theta, KERNEL_OUTPUTS)]
            if motor_driven(study, pr.cfg) else
            [gas_outputs(pr.cfg, study.booster_pressure, w, theta, KERNEL_OUTPUTS) for w in speeds])
    speeds = [w for w, _, _ in runs]
    return speeds, {w: g for w, g, _ in runs}, _stacked([rev for _, _, rev in runs])


def _asked(study, name) -> bool:
    """An output the study reports (per-vane friction powers come with friction_power)."""
    return name in study.outputs or (name.startswith("friction_power_") and "friction_power" in study.outputs)


def revolutions(kern, P, theta, omega) -> list[dict]:
    """Per design (rows of P): its kernel outputs over its uniform revolution (theta (D, n) or
    (n,), from `revolution`) at speed omega (D,) -- through one vane where its vanes are alike
    (alike.py: vane outputs (1, n)), else every vane's (N, n). A design gets the same bits in any
    batch."""
    P = np.atleast_2d(np.asarray(P, dtype=float))
    D, n = len(P), np.shape(theta)[-1]
    theta, omega = np.broadcast_to(theta, (D, n)), np.broadcast_to(np.asarray(omega, dtype=float), (D,))
    one = one_vane(kern.structure)
    same = one.alike(P, n) if one is not None else np.zeros(D, bool)
    out = [None] * D
    for idx, ov in ((np.flatnonzero(same), one), (np.flatnonzero(~same), None)):
        if len(idx):
            ev = (ov.evaluate(P[idx], theta[idx], omega[idx], KERNEL_OUTPUTS) if ov is not None
                  else evaluate_designs(kern, P[idx], theta[idx], omega[idx]))
            for i, d in enumerate(idx):
                out[d] = {nm: a[i] for nm, a in ev.items()}
    return out


def _stacked(evs: list) -> dict:
    return {nm: np.stack([ev[nm] for ev in evs]) for nm in evs[0]}


def _verdict(kern, pr, theta, ev, w0):
    """geometry_verdict of one design (its speeds' outputs ev); a design evaluated through one
    vane and rejected is evaluated on every vane (at its first speed w0) for the reason: which
    vane, at which angle, as the N-vane kernel's rounding has it."""
    alpha, pts, curv = housing_check_samples(kern, pr.p, theta.size)
    s, res = ev["s"][0], ev["position_residual"][0]
    if s.shape[0] != kern.structure.vanes:
        full = spread({"s": s[None], "position_residual": res[None]}, kern.structure.vanes, theta.size)
        if geometry_verdict(pr.values, alpha, pts, curv, theta, full["s"][0], full["position_residual"][0]) is None:
            return None
        ev = evaluate_designs(kern, pr.p[None, :], theta, np.array([w0]))
        s, res = ev["s"][0], ev["position_residual"][0]
    return geometry_verdict(pr.values, alpha, pts, curv, theta, s, res)


def _evaluate_one(study, kern, pr, nrev, ev=None):
    """(status, [(speed, outputs or None)] or None) of one prepared design; `ev`: its kernel
    outputs at design_speeds when a batch computed them already (pre_evaluated)."""
    theta = revolution(pr.cfg.angle, nrev)
    speeds = design_speeds(study, pr.cfg)
    run = lambda ws: _stacked(revolutions(kern, np.repeat(pr.p[None, :], len(ws), axis=0), theta,  # noqa: E731
                                          np.asarray(ws)))
    try:  # (the positions, hence the geometry verdict, do not depend on the speed)
        if ev is None:
            ev = run(np.nan_to_num(speeds, nan=1.0))
        verdict = _verdict(kern, pr, theta, ev, np.nan_to_num(speeds, nan=1.0)[0])
    except PumpsimError as e:
        return f"numerical: {e}", None
    if verdict:
        return f"geometry: {verdict}", None
    try:
        speeds, gas, pumping = _gas_points(study, pr, speeds, theta)
        ev = ev if pumping is None else pumping
    except PumpsimError as e:
        return f"numerical: gas model (spec §8): {e}", None
    res = ev["position_residual"]
    if not np.all(np.isfinite(res)) or np.nanmax(res) > POSITION_TOL:
        return "numerical: position problem did not converge", None
    const = pr.constants()
    per_speed = []
    for k, w in enumerate(speeds):
        a = {nm: arr[k] for nm, arr in ev.items()}
        out, _ = reduce_revolution(a, const, vanes=kern.structure.vanes)
        out.update(gas.get(w, {}))
        if not all(np.isfinite(x) for o, x in out.items() if not isinstance(x, bool) and _asked(study, o)):
            out = None
        per_speed.append((w, out))
    return "ok", per_speed


BATCH_DESIGNS = 64  # designs per kernel call: ~13 MB of outputs at 360 samples, 4 vanes


def batch_designs(vanes: int, one_vane: bool) -> int:
    """Designs per kernel call: BATCH_DESIGNS on every vane; through one vane of N, N times as
    many -- the same memory, and fewer calls (measured: 256 designs per call through one vane of
    four took ~6 % less CPU than 64)."""
    return BATCH_DESIGNS * (vanes if one_vane else 1)


def pre_evaluated(study, kern, prepared: dict, members, nrev) -> dict:
    """{design index: kernel outputs at its design_speeds} for the designs `members` of one
    variant, BATCH_DESIGNS per kernel call (a batch that fails is left out: its designs then run
    alone and each reports its own failure)."""
    found: dict = {}
    for lo in range(0, len(members), BATCH_DESIGNS):
        rows = [(j, w) for j in members[lo:lo + BATCH_DESIGNS]
                for w in np.nan_to_num(design_speeds(study, prepared[j].cfg), nan=1.0)]
        try:
            evs = revolutions(kern, np.array([prepared[j].p for j, _ in rows]),
                              np.array([revolution(prepared[j].cfg.angle, nrev) for j, _ in rows]),
                              np.array([w for _, w in rows]))
        except PumpsimError:
            continue
        for j in members[lo:lo + BATCH_DESIGNS]:
            found[j] = _stacked([ev for (i, _), ev in zip(rows, evs) if i == j])
    return found


CONTACT_REVOLUTIONS = 30  # simulated from an in-contact start; the last one is reported


def _evaluate_contact(study, pr, nrev):
    """Model 1 (penalty contact) at constant speed: simulated for study.revolutions from the
    in-contact start, the last revolution sampled at the same angles as Model 2 is reported if it
    repeats the one before (periodic steady state within tolerances.CONTACT_PERIODIC_REL)."""
    import dataclasses

    from ..contact import simulate_contact
    from ..errors import SolverError
    from ..geometry import vane_positions

    kern2 = load_kernels(pr.cfg.structure_for("constrained"))
    theta = revolution(pr.cfg.angle, nrev)
    s, _, res = vane_positions(kern2, pr.p, theta)
    alpha, pts, curv = housing_check_samples(kern2, pr.p, nrev)
    verdict = geometry_verdict(pr.values, alpha, pts, curv, theta, s, res)
    if verdict:
        return f"geometry: {verdict}", None
    const = pr.constants()
    revs = study.revolutions or CONTACT_REVOLUTIONS
    per_speed = []
    for w in design_speeds(study, pr.cfg):
        cfg = dataclasses.replace(pr.cfg, mode="speed", speed=float(w), speed_ripple=None)
        rate = nrev * w / (2 * math.pi)
        try:
            r = simulate_contact(cfg, duration=(revs * nrev - 0.5) / rate, rate=rate, initial="housing")
        except SolverError as e:
            return f"numerical: {e}", None
        last, prev = slice(-nrev, None), slice(-2 * nrev, -nrev)
        tq = r.torque
        drift = np.abs(tq[last] - tq[prev]).max() / max(np.abs(tq[last]).max(), 1e-300)
        if drift > CONTACT_PERIODIC_REL:
            return (f"not_periodic: the contact model's torque still changes by {100 * drift:.2g} % of its "
                    f"range between revolutions {revs - 1} and {revs} (raise study.revolutions)"), None
        a = {"torque": tq[last], **{k: r.vanes[k][:, last] for k in ("s", "sdot", "normal", "slot1", "slot2")},
             **{k: r.extra[k][:, last] for k in ("tip_slip", "mu_housing", "mu_slot")}}
        a["n_consistent"] = np.ones_like(a["s"])
        a["ambiguity"] = np.zeros_like(a["s"])
        out, _ = reduce_revolution(a, const)
        out["lift_off"] = bool(out["min_normal_force"] <= 0)  # the penalty force never pulls: 0 is no contact
        out["paradox"] = any("friction paradox" in msg for msg in r.warnings)
        per_speed.append((w, out))
    return "ok", per_speed


def _housing_clear(kern, dm, P, nrev) -> np.ndarray:
    """(B,) bool: the housing holds each design's rotor circle as geometry_verdict asks (screen.py):
    the base ellipse from its closed form where that decides, else from its samples (NumPy, or
    the compiled curve with harmonics)."""
    rr = P[:, dm.index["rotor.radius"]]
    if kern.structure.harmonics:
        _, pts, curv = housing_batch(kern, P, nrev)
        return polygon_clear(rr, pts, curv)
    clear = ellipse_clear(P, dm.index, rr, nrev)
    if not clear.all():
        rest = np.flatnonzero(~clear)
        _, pts, margin = housing_samples(P[rest], dm.index, nrev)
        clear[rest] = polygon_clear(rr[rest], pts, None, margin)
    return clear


def _mapped_batch(study, dm, kern, P, speed, nrev, theta, one=None) -> list | None:
    """[(status, [(speed, outputs or None)] or None)] of B admitted designs of one variant
    (DesignMap rows P, speeds): one kernel call (`one`: alike.OneVane, when every design's vanes
    are alike), the housing, the geometry and the reductions as array operations. None when the
    kernel fails (then each design runs alone); an entry None: a design the geometry screen does
    not admit, left to the per-design path for the config's own verdict."""
    W = list(study.speeds) if study.speeds else None
    S, B = (len(W) if W else 1), len(P)
    omega = np.tile(np.asarray(W, dtype=float), B) if W else speed
    PS = np.repeat(P, S, axis=0)
    col = lambda k: P[:, dm.index[k]]  # noqa: E731
    lm = np.asarray(mouth_depths(dm.index, P))
    width = get_value(dm.table, "rotor.width")
    const = {"c_visc": col("effects.viscous_tip_friction"), "L": col("vane.length"), "lm": lm,
             "tip_area": width * col("vane.thickness") if width else np.full(B, math.nan)}
    try:
        out, converged, s_min, s_max = _batch_outputs(kern, one, PS, theta, omega,
                                                      {k: np.repeat(v, S) for k, v in const.items()})
        clear = _housing_clear(kern, dm, P, nrev)
    except PumpsimError:
        return None
    good = clear & extension_ok(col("vane.length"), lm, converged[::S], s_min[::S], s_max[::S])
    good &= col("vane.thickness") < slot_room(col("rotor.radius"), kern.structure.vanes)
    asked = [o for o in out if o not in BOOL_OUTPUTS and _asked(study, o)]
    fin = np.all([np.isfinite(out[o]) for o in asked], axis=0) if asked else np.ones(B * S, bool)
    block = Block(out, omega, fin, S)
    converged = converged.reshape(B, S).all(axis=1)
    return [None if not good[d] else ("ok", block.design(d)) if converged[d]
            else ("numerical: position problem did not converge", None) for d in range(B)]


def _batch_outputs(kern, one, PS, theta, omega, const) -> tuple:
    """fused.fused_outputs of designs PS (rows of the variant's parameter vectors; `one`: through
    alike.OneVane) through the SIMD library's reduction entry where it has one, else from the
    kernel's outputs by reduce_batch (the same numbers)."""
    fast = one.fast if one is not None else fast_kernel(kern.structure)
    if fast is not None and fast.has_reductions:
        if one is not None:
            return fused_outputs(fast, PS[:, one.columns], theta, omega, {**const, "bearing": PS[:, one.bearing]},
                                 one.vanes)
        return fused_outputs(fast, PS, theta, omega, {**const, "bearing": 0.0})
    ev = one.evaluate(PS, theta, omega, KERNEL_OUTPUTS) if one else evaluate_designs(kern, PS, theta, omega)
    return (reduce_batch(ev, const, kern.structure.vanes)[0], *position_checks(ev["s"], ev["position_residual"]))


def _mapped_results(study, X, results: dict, speeds_of: dict) -> list:
    """Results of the designs DesignMap covers, into `results` (design row -> (status,
    per_speed)) and `speeds_of`; returns the rows left to the per-design path."""
    nrev = study.revolution_samples
    maps, rest = design_maps(study, X)
    rest = list(rest)
    for dm, members in maps:
        P, speed, ok = dm.vectors(X[members])
        adm = np.flatnonzero(ok)
        rest += members[~ok].tolist()
        if not len(adm):
            continue
        j0 = members[adm[0]]
        try:
            kern = load_kernels(dm.structure)
        except PumpsimError:
            kern = None
        if kern is None or not dm.agrees(P[adm[0]], speed[adm[0]], dict(zip(study.keys, X[j0].tolist()))):
            rest += members[adm].tolist()
            continue
        theta = revolution(dm.cfg.angle, nrev)
        one = one_vane(dm.structure)
        same = one.alike(P[adm], nrev) if one is not None else np.zeros(len(adm), bool)
        for group, ov in ((adm[same], one), (adm[~same], None)):
            rest += _mapped_group(study, dm, kern, P, speed, nrev, theta, ov, group, members, results, speeds_of)
    return sorted(rest)


def _mapped_group(study, dm, kern, P, speed, nrev, theta, one, group, members, results, speeds_of) -> list:
    """_mapped_batch over the rows `group` of P, batch_designs at a time; returns the design rows
    left to the per-design path."""
    rest, size = [], batch_designs(dm.structure.vanes, one is not None)
    for lo in range(0, len(group), size):
        idx = group[lo:lo + size]
        try:
            got = _mapped_batch(study, dm, kern, P[idx], speed[idx], nrev, theta, one)
        except Exception:  # noqa: BLE001 - then each design runs alone and reports its own failure
            interrupt.check()
            got = None
        if got is None:
            rest += members[idx].tolist()
            continue
        for i, r in zip(idx, got):
            if r is None:
                rest.append(int(members[i]))
                continue
            results[members[i]] = r
            speeds_of[members[i]] = list(study.speeds) if study.speeds else [float(speed[i])]
    return rest


def _per_design_results(study, X, todo, results: dict, speeds_of: dict) -> None:
    """Results of the designs `todo` (rows of X), each from its own validated config."""
    keys, nrev = study.keys, study.revolution_samples
    prepared = {j: prepare(study, dict(zip(keys, X[j]))) for j in todo}
    groups: dict = {}
    for j, pr in prepared.items():
        if pr.status == "ok":
            groups.setdefault(pr.cfg.structure_for("constrained"), []).append(j)
            speeds_of[j] = design_speeds(study, pr.cfg)
        else:
            speeds_of[j] = study.speeds or [dict(zip(keys, X[j])).get(SPEED_KEY, study.base_speed)]
            results[j] = (pr.status, None)
    for structure, members in groups.items():
        try:
            kern = load_kernels(structure)
        except PumpsimError as e:  # a worker that cannot build the variant: every design says so
            for j in members:
                results[j] = (f"kernel: {e}", None)
            continue
        batch = {} if study.model == "contact" else pre_evaluated(study, kern, prepared, members, nrev)
        for j in members:
            try:
                if study.model == "contact":
                    results[j] = _evaluate_contact(study, prepared[j], nrev)
                else:
                    results[j] = _evaluate_one(study, kern, prepared[j], nrev, batch.get(j))
            except Exception as e:  # noqa: BLE001 - one design's failure never stops the study
                interrupt.check()  # unless the failure was a signal's doing
                results[j] = (f"error: {type(e).__name__}: {e}", None)


def design_results(study, X: np.ndarray) -> tuple[dict, dict]:
    """(design row -> (status, per-speed results), design row -> speeds) of the designs X: those
    DesignMap covers as parameter vectors (per-speed results: a columns.BlockDesign), the others
    each from its own config ([(speed, outputs or None)])."""
    results, speeds_of = {}, {}
    todo = _mapped_results(study, X, results, speeds_of)
    _per_design_results(study, X, todo, results, speeds_of)
    return results, speeds_of


def evaluate_pump_rows(study, X: np.ndarray, ids, n_vanes_max: int) -> list[dict]:
    """Rows (one per design and speed) for the designs `ids` with key values X (designs, keys)."""
    return rows(study, X, ids, *design_results(study, X))


def evaluate_rows(study, X, ids, n_vanes_max: int) -> list[dict]:
    if study.function is not None:
        from .analytic import FUNCTIONS

        fn = FUNCTIONS[study.function]
        Y = fn(X)
        return [{"design": int(i), **{k: float(x) for k, x in zip(study.keys, xs)},
                 **{o: float(y) for o, y in zip(fn.outputs, ys)}, "status": "ok"}
                for i, xs, ys in zip(ids, X, Y)]
    return evaluate_pump_rows(study, X, ids, n_vanes_max)


def evaluate_table(study, X, ids):
    """The Arrow table of the designs `ids` (key values X): evaluate_rows' rows, built as columns."""
    if study.function is not None:
        return rows_to_table(study, evaluate_rows(study, X, ids, max_vanes(study)))
    return columns_to_table(study, table_columns(study, X, ids, *design_results(study, X), columns(study)))


__all__ = ["evaluate_designs", "kernel_tangents", "evaluate_rows", "evaluate_table", "revolution", "per_vane_name"]
