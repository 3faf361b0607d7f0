"""The constant-speed model's torque over many samples through the SIMD library, and its pointwise
derivatives by the fitted values from the library's Jacobian entries (identification's fast path;
problem.sample_torque, the CasADi map, is the reference and the fallback)."""
from __future__ import annotations

import numpy as np

from ..data import Dataset
from ..kernels import FAST_THREADED, default_threads, fast_kernel
from ..model_spec.parameters import KERNEL_GRAPH_INPUTS
from ..motion import ripple_motion

from .runs import JACOBIAN_RUNS

SAMPLE_BLOCK = 1 << 16  # samples per block of a SIMD torque evaluation: its temporaries stay ~0.5 MB


def sample_blocks(n: int):
    """Slices of SAMPLE_BLOCK samples (a multiple of the SIMD library's chunk: the same bits as
    one call over all samples)."""
    return [slice(lo, min(n, lo + SAMPLE_BLOCK)) for lo in range(0, n, SAMPLE_BLOCK)]


def simd_torque(fast, theta, z, k, tau, g, gd) -> np.ndarray:
    """problem.torque_at on the SIMD library `fast`: the torque alone, block by block into one
    array (at 10^6 samples the speed and acceleration temporaries are those of a block)."""
    npar = fast.n_params
    zs = z[npar:npar + len(KERNEL_GRAPH_INPUTS)]
    n = np.size(theta)
    tau, g, gd = (np.broadcast_to(np.asarray(a, dtype=float), (n,)) for a in (tau, g, gd))
    tq = np.empty(n)
    row = tq.reshape(1, n)
    for sl in sample_blocks(n):
        m = sl.stop - sl.start
        w, wd = _drive(zs, k, tau[sl], g[sl], gd[sl])
        fast(theta[sl], np.broadcast_to(w, (m,)), np.broadcast_to(wd, (m,)), z[:npar], out=row[:, sl],
             threads=default_threads() if m >= FAST_THREADED else 1, outputs="torque")
    tq += zs[3]
    return tq


DESIGN_SAMPLES = 1 << 19  # samples per SIMD call of simd_torque_designs (~4 MB per input array)


def simd_torque_designs(fast, thetas, zs, k, tau, g, gd) -> np.ndarray:
    """simd_torque for D designs on one drive: angles thetas (D, n) and kernel-graph inputs zs
    (D, len z) -> torques (D, n), bit for bit D calls of simd_torque: each design is one block of
    the library's blocks entry, evaluated from its own start as a call over its n samples is. Many
    short evaluations (the sub-sample points of an interval average) then cost one Python call per
    DESIGN_SAMPLES samples, not one per design, and reach the threaded size."""
    thetas, zs = np.ascontiguousarray(np.atleast_2d(thetas), dtype=float), np.atleast_2d(zs)
    D, n = thetas.shape
    npar = fast.n_params
    out = np.empty((D, n))
    if n > SAMPLE_BLOCK or D == 1:
        for d in range(D):
            out[d] = simd_torque(fast, thetas[d], zs[d], k, tau, g, gd)
        return out
    tau, g, gd = (np.broadcast_to(np.asarray(a, dtype=float), (n,)) for a in (tau, g, gd))
    drive = zs[:, npar:npar + len(KERNEL_GRAPH_INPUTS)]
    same = bool(np.all(drive == drive[0]))
    motion = [_drive(drive[0], k, tau, g, gd)] if same else [_drive(zd, k, tau, g, gd) for zd in drive]
    motion = [tuple(np.broadcast_to(a, (n,)) for a in m) for m in motion]
    group = max(1, DESIGN_SAMPLES // n)
    for lo in range(0, D, group):
        hi = min(D, lo + group)
        m = (hi - lo) * n
        w, wd = (np.concatenate([motion[0 if same else d][i] for d in range(lo, hi)]) for i in (0, 1))
        row = out[lo:hi].reshape(1, m)
        fast(thetas[lo:hi].reshape(m), w, wd, np.ascontiguousarray(zs[lo:hi, :npar]), block=n, out=row,
             threads=default_threads() if m >= FAST_THREADED else 1, outputs="torque")
    out += drive[:, 3:4]
    return out


def _drive(zs, k, tau, g, gd):
    """Speed and acceleration of the drive at drive times tau (zs: z's drive entries)."""
    theta0, w0, delay, _, rc, rs = zs
    if rc == 0 and rs == 0:  # no ripple: drive_motion's speed and acceleration, bit for bit
        return w0 * g, w0 * gd
    _, w, wd = drive_motion(theta0 + w0 * (tau - delay), theta0, w0, rc, rs, k, g, gd)
    return w, wd


def drive_motion(theta_n, theta_start, omega0, rc, rs, k, g, gd, lib=np):
    """ripple_motion in the drive time tau (theta_n = theta_start + omega0 (tau - delay)), then
    the speed and acceleration in real time: omega = (dtheta/dtau) g, omegadot = (d2theta/dtau2)
    g^2 + (dtheta/dtau) gd. g = 1, gd = 0 (a constant speed) leave ripple_motion's values as they are."""
    theta, w, wd = ripple_motion(theta_n, theta_start, omega0, rc, rs, k, lib)
    return theta, w * g, wd * g * g + w * gd


def simd_jacobian(structure):
    """The SIMD library with Jacobian entries for this variant, or None (then the CasADi map)."""
    fast = fast_kernel(structure)
    return fast if fast is not None and fast.has_jacobian else None


def drive_tangents(tau, zs, k, g, gd, seeds):
    """d omega and d omegadot per sample (n, m) along the m columns `seeds` of the drive's entries
    of z (theta0, speed, delay, torque_offset, ripple_cos, ripple_sin; rows as KERNEL_GRAPH_INPUTS):
    drive_motion differentiated -- omega = omega0 (1 + rc cos(k thn) - rs sin(k thn)) g, omegadot =
    -k omega0^2 (rc sin + rs cos) g^2 + omega_r gd at the nominal angle thn = theta0 + omega0 (tau -
    delay)."""
    th0, w0, dl, _, rc, rs = zs
    d0, dw0, ddl, _, drc, drs = (np.asarray(r)[None, :] for r in seeds)
    tau, g, gd = (np.asarray(a, dtype=float)[:, None] for a in (tau, g, gd))
    if rc == 0 and rs == 0 and not drc.any() and not drs.any():  # no ripple, none fitted: the terms
        dw_r = np.broadcast_to(dw0, (tau.shape[0], dw0.shape[1]))  # below without their sines (zeros)
        return dw_r * g, dw_r * gd
    thn = th0 + w0 * (tau - dl)
    c, s = np.cos(k * thn), np.sin(k * thn)
    dthn = d0 + dw0 * (tau - dl) - ddl * w0
    rsc = rc * s + rs * c
    dw_r = -k * w0 * rsc * dthn + dw0 * (1 + rc * c - rs * s) + w0 * (drc * c - drs * s)
    dwd_r = (-k * k * w0 * w0 * (rc * c - rs * s) * dthn - 2 * k * w0 * rsc * dw0
             - k * w0 * w0 * (drc * s + drs * c))
    return dw_r * g, dwd_r * g * g + dw_r * gd


def pointwise_columns(fast, theta, z, k, kin, seeds):
    """The torque at theta (as torque_at) and its derivatives along the columns of `seeds` (dz/dx,
    rows as z: the runtime parameters, then KERNEL_GRAPH_INPUTS) with theta held: the library's
    exact derivatives by p along each column and by omega and omegadot (when the drive moves),
    chained with drive_tangents; the torque offset's column added. Block by block (SAMPLE_BLOCK),
    into one (n, m) array."""
    npar, n, m = fast.n_params, np.size(theta), seeds.shape[1]
    zs, sd = z[npar:npar + len(KERNEL_GRAPH_INPUTS)], seeds[npar:]
    moves = bool(np.any(np.delete(sd, 3, axis=0)))  # every drive entry but the torque offset
    dirs = np.zeros((m + 2 * moves, 3 + npar))
    dirs[:m, 3:] = seeds[:npar].T
    if moves:
        dirs[m, 1] = dirs[m + 1, 2] = 1.0
    tau, g, gd = (np.broadcast_to(np.asarray(a, dtype=float), (n,)) for a in kin)
    tq, J = np.empty(n), np.empty((n, m))
    buf = fast.jacobian_array(min(n, SAMPLE_BLOCK), dirs.shape[0])
    for sl in sample_blocks(n):
        b = sl.stop - sl.start
        w, wd = _drive(zs, k, tau[sl], g[sl], gd[sl])
        w, wd = np.broadcast_to(w, (b,)), np.broadcast_to(wd, (b,))
        run = lambda: fast.jacobian(theta[sl], w, wd, z[:npar], dirs, out=buf[:, :b],  # noqa: E731
                                    threads=default_threads() if b >= FAST_THREADED else 1)
        # a long record's blocks are not remembered: each is short enough for the memory, and 32 of
        # them held ~120 MiB on a 10^6-sample fit (a long run is rarely repeated)
        tq[sl], D = run() if n > SAMPLE_BLOCK else JACOBIAN_RUNS.get(
            ("jacobian", fast, z[:npar].tobytes(), dirs.tobytes(), dirs.shape), (theta[sl], w, wd), run)
        J[sl] = D[:m].T
        if moves:
            dw, dwd = drive_tangents(tau[sl], zs, k, g[sl], gd[sl], sd)
            J[sl] += D[m][:, None] * dw + D[m + 1][:, None] * dwd
    tq += zs[3]
    J += sd[3][None, :]
    return tq, J


def drive_kinematics(data: Dataset, t):
    """(tau, g, gd): the drive time and its first two rates per sample. With a speed column whose
    slow trend is significant against its noise (data.speed_trend(): a Legendre fit, see there)
    tau = integral of omega_s / mean(speed): the model's angle is theta0 + the integral of the
    smoothed measured speed, its speed and acceleration those of the trend (the column's noise
    never enters omegadot). Otherwise tau is t itself (the same array), g = 1, gd = 0 -- the
    constant-speed model as it always was (g and gd read-only views of one number: no memory)."""
    trend = data.speed_trend()
    if trend is None:
        return t, np.broadcast_to(1.0, t.shape), np.broadcast_to(0.0, t.shape)
    return (trend.warped_time(t), trend.speed(t) / trend.mean, trend.acceleration(t) / trend.mean)


def drive_note(data: Dataset) -> str:
    tr = data.speed_trend()
    return (f"; the speed column drifts ({100 * tr.change():.2g} % over the record, F-test p = "
            f"{tr.p_value:.2g}): angle and speed follow its Legendre trend of degree {tr.degree}")
