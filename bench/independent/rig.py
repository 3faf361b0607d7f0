"""An independent implementation of the constrained model (spec §1-4, Model 2) by inverse dynamics.

Written from /work/shared/spec/MODEL.md §1-7 and the engineering report only; it imports nothing
from pumpsim/ or codegen/ (numpy only), so its torque is a cross-check of pumpsim's, not a copy.

Derivation (own, analytic; no finite differences):
* Housing as an implicit curve H(P) = |P - C_h| - f(alpha) = 0, alpha the polar angle about C_h,
  f = r0 (circle R, or ellipse ab/sqrt(b^2 cos^2 phi + a^2 sin^2 phi), phi = alpha - psi) plus the
  harmonics sum A_k cos(k(alpha - psi - gamma_k)). In polar coordinates about C_h:
      grad H = e_r - f'/r e_a,
      hess H = e_a e_a^T (1/r - f''/r^2) + f'/r^2 (e_r e_a^T + e_a e_r^T).
  H > 0 outside, so the inward normal is n = -grad H/|grad H| and t = z x n.
* Tip B = Rot(theta)(Ob + (s + L) u) (tip radius 0). s(theta) from Newton on H(B) = 0 (dH/ds = grad H . U).
* Differentiating H(B(t)) = 0 twice in time (U = Rot(theta) u, ' = d/dt):
      B' = omega z x B + s' U,                   s' = -omega g.(z x B) / g.U,
      g.B'' + B'^T hess B' = 0 with B'' = omega' z x B + omega z x B' + s'' U + s' omega z x U,
  solved for s''. The mass centre G = Rot(theta)(Ob + (s + L/2) u) then has
      a_G = omega' z x G - omega^2 G + 2 s' omega z x U + s'' U.
* Per vane and sample the three reactions (N, F1, F2) solve the 3x3 linear system of spec §3
  (force balance in x, y; moment about G with J omega') for each of the four slot contact-side sign
  sets (sigma1, sigma2); a set is consistent when sigma_j F_j >= 0. The set with the smallest
  violation is taken; two consistent sets that differ are counted as a friction paradox.
* Drive torque (spec §3): tau = I_r omega' + tau_bearing + sum over vanes of the z-moments about O
  of the slot-wall forces on the vane (the rotor gets their opposite).

Assumptions: tip radius rho = 0 (the report's point tip); omega > 0; friction law exactly the spec's
Adams-style cubic STEP law, with the slot law taken as the housing law when friction.slot is absent.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


def step(x, x0, h0, x1, h1):
    d = np.clip((x - x0) / (x1 - x0), 0.0, 1.0)
    return h0 + (h1 - h0) * d * d * (3.0 - 2.0 * d)


@dataclass(frozen=True)
class Friction:
    static: float
    dynamic: float
    v_static: float = 1.0e-4
    v_dynamic: float = 1.0e-3

    def mu(self, v):
        """Spec §3 law, odd in v."""
        v = np.asarray(v, dtype=float)
        a = np.abs(v)
        low = step(v, -self.v_static, -self.static, self.v_static, self.static)
        mid = np.sign(v) * step(a, self.v_static, self.static, self.v_dynamic, self.dynamic)
        high = np.sign(v) * self.dynamic
        return np.where(a <= self.v_static, low, np.where(a <= self.v_dynamic, mid, high))

    def scaled(self, factor):
        return replace(self, static=self.static * factor, dynamic=self.dynamic * factor)


@dataclass(frozen=True)
class Rig:
    """A pump's geometry and friction (spec §5 keys, SI)."""
    name: str
    shape: str = "circle"            # circle | ellipse
    radius: float = 0.0225           # circle
    a: float = 0.0245                # ellipse semi-axes
    b: float = 0.0215
    harmonics: tuple = ()            # ((k, A_k, gamma_k), ...)
    center: tuple = (0.0, 0.0)
    angle: float = 0.0               # housing angle psi
    rotor_radius: float = 0.020
    rotor_inertia: float = 2.0e-5
    vanes: int = 4
    slot_radius: float = 0.009
    slot_tilt: float = 0.0
    first_slot_angle: float = 0.0
    length: float = 0.012
    thickness: float = 0.003
    mass: float = 0.0012
    vane_inertia: float | None = None
    tip: Friction = field(default_factory=lambda: Friction(0.21, 0.20))
    slot: Friction | None = None     # None: same as tip (spec §5)
    speed: float = 607.37
    bearing_torque: float = 0.0

    @property
    def J(self):
        if self.vane_inertia is not None:
            return self.vane_inertia
        return self.mass * (self.length ** 2 + self.thickness ** 2) / 12.0

    @property
    def slot_friction(self):
        return self.slot if self.slot is not None else self.tip

    # ---- housing polar radius f(alpha) and its first two derivatives
    def polar(self, alpha):
        phi = alpha - self.angle
        if self.shape == "circle":
            f = np.full_like(phi, self.radius)
            f1 = np.zeros_like(phi)
            f2 = np.zeros_like(phi)
        else:
            a, b = self.a, self.b
            D = (b * np.cos(phi)) ** 2 + (a * np.sin(phi)) ** 2
            D1 = (a * a - b * b) * np.sin(2 * phi)
            D2 = 2 * (a * a - b * b) * np.cos(2 * phi)
            f = a * b * D ** -0.5
            f1 = -0.5 * a * b * D ** -1.5 * D1
            f2 = a * b * (0.75 * D ** -2.5 * D1 ** 2 - 0.5 * D ** -1.5 * D2)
        for k, A, g in self.harmonics:
            c = k * (phi - g)
            f = f + A * np.cos(c)
            f1 = f1 - k * A * np.sin(c)
            f2 = f2 - k * k * A * np.cos(c)
        return f, f1, f2

    def slot_frame(self, i):
        """Rotor-frame Ob, u, w and the mouth distance l_m of slot i."""
        phi = self.first_slot_angle + 2 * np.pi * i / self.vanes
        ob = self.slot_radius * np.array([np.cos(phi), np.sin(phi)])
        u = np.array([np.cos(phi + self.slot_tilt), np.sin(phi + self.slot_tilt)])
        w = np.array([-u[1], u[0]])
        p = ob @ u
        lm = -p + np.sqrt(p * p - ob @ ob + self.rotor_radius ** 2)
        return ob, u, w, lm


def _rot(theta, v):
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]], axis=-1)


def _zx(v):
    """z x v for arrays (..., 2)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def housing_terms(rig, P):
    """H, grad H and hess H (spec §1 housing as H(P) = |P - C_h| - f(alpha))."""
    d = P - np.asarray(rig.center)
    r = np.hypot(d[..., 0], d[..., 1])
    alpha = np.arctan2(d[..., 1], d[..., 0])
    f, f1, f2 = rig.polar(alpha)
    er = d / r[..., None]
    ea = _zx(er)
    g = er - (f1 / r)[..., None] * ea
    ee = ea[..., :, None] * ea[..., None, :]
    sym = er[..., :, None] * ea[..., None, :] + ea[..., :, None] * er[..., None, :]
    hess = (1 / r - f2 / r ** 2)[..., None, None] * ee + (f1 / r ** 2)[..., None, None] * sym
    return r - f, g, hess


def vane_kinematics(rig, i, theta, omega, domega):
    """s, s', s'' and the inertial points/directions of vane i along a rotor motion."""
    ob, u, w, lm = rig.slot_frame(i)
    U, W = _rot(theta, u), _rot(theta, w)
    Ob = _rot(theta, ob)
    s = np.full(theta.shape, 0.5 * lm)
    for _ in range(60):
        B = Ob + (s + rig.length)[:, None] * U
        H, g, _h = housing_terms(rig, B)
        ds = H / _dot(g, U)
        s = s - ds
        if np.max(np.abs(ds)) < 1e-16:
            break
    B = Ob + (s + rig.length)[:, None] * U
    H, g, hess = housing_terms(rig, B)
    gU = _dot(g, U)
    sd = -omega * _dot(g, _zx(B)) / gU
    Bd = omega[:, None] * _zx(B) + sd[:, None] * U
    quad = np.einsum("ni,nij,nj->n", Bd, hess, Bd)
    known = domega[:, None] * _zx(B) + omega[:, None] * _zx(Bd) + (sd * omega)[:, None] * _zx(U)
    sdd = -(quad + _dot(g, known)) / gU
    if np.any(s < 0) or np.any(s >= lm) or np.any(s + rig.length <= lm):
        raise ValueError(f"{rig.name}: vane {i} leaves its slot (s in [{s.min():.5f}, {s.max():.5f}], l_m {lm:.5f})")
    n = -g / np.linalg.norm(g, axis=-1)[:, None]
    return dict(s=s, sd=sd, sdd=sdd, U=U, W=W, Ob=Ob, B=B, Bd=Bd, n=n, t=_zx(n), lm=lm)


SIGNS = ((1, 1), (1, -1), (-1, 1), (-1, -1))


def vane_reactions(rig, k, theta, omega, domega, tip_factor=1.0, slot_factor=1.0, tip_viscous=0.0,
                   mass_factor=1.0):
    """Reactions N, F1, F2 and the vane's drive-torque share (z-moment about O of its slot forces).

    tip_viscous (s/m): the tip COF grows with slip speed, mu_h(v) + tip_viscous * v (a lubricated
    tip's rising Stribeck branch) - this generator's own form of viscous tip friction.
    mass_factor: this vane's mass (and inertia) over the rig's (a heavier vane: out of pumpsim's library).
    """
    m, J, h2 = rig.mass * mass_factor, rig.J * mass_factor, 0.5 * rig.thickness
    U, W, B, n, t = k["U"], k["W"], k["B"], k["n"], k["t"]
    G = k["Ob"] + (k["s"] + 0.5 * rig.length)[:, None] * U
    Gd = omega[:, None] * _zx(G) + k["sd"][:, None] * U
    aG = domega[:, None] * _zx(G) + omega[:, None] * _zx(Gd) + (k["sd"] * omega)[:, None] * _zx(U) \
        + k["sdd"][:, None] * U
    A = k["Ob"] + k["s"][:, None] * U
    M = k["Ob"] + k["lm"] * U
    vt = _dot(k["Bd"], t)
    mu_h = tip_factor * rig.tip.mu(vt) + tip_viscous * vt
    mu_r = slot_factor * rig.slot_friction.mu(k["sd"])
    fN = n - mu_h[:, None] * t
    rhs = np.stack([m * aG[:, 0], m * aG[:, 1], J * domega], axis=-1)
    best, viol_best, consistent = None, None, 0
    for s1, s2 in SIGNS:
        f1 = W - (mu_r * s1)[:, None] * U
        f2 = W - (mu_r * s2)[:, None] * U
        P1 = A - s1 * h2 * W
        P2 = M - s2 * h2 * W
        mat = np.stack([np.stack([fN[:, 0], f1[:, 0], f2[:, 0]], -1),
                        np.stack([fN[:, 1], f1[:, 1], f2[:, 1]], -1),
                        np.stack([_cross(B - G, fN), _cross(P1 - G, f1), _cross(P2 - G, f2)], -1)], 1)
        x = np.linalg.solve(mat, rhs[..., None])[..., 0]
        scale = np.abs(x).max(axis=1) + 1e-300
        viol = np.maximum(0, -s1 * x[:, 1]) + np.maximum(0, -s2 * x[:, 2])
        ok = viol <= 1e-9 * scale
        consistent = consistent + ok
        tau = _cross(P1, x[:, 1:2] * f1) + _cross(P2, x[:, 2:3] * f2)
        cand = np.column_stack([x, tau])
        if best is None:
            best, viol_best = cand, viol
        else:
            better = viol < viol_best
            best = np.where(better[:, None], cand, best)
            viol_best = np.minimum(viol, viol_best)
    return dict(N=best[:, 0], F1=best[:, 1], F2=best[:, 2], tau=best[:, 3],
                paradox=int(np.sum(consistent == 0)), vt=vt)


def motion(t, speed, theta0=0.0, ripple=None, drift=None):
    """theta, omega, omega' of a constant speed, optionally with a ripple (order k, rel. amplitude eps,
    phase): + speed eps cos(k speed t + phase), and a slow linear drift (rel. change d over the time
    span D, centred at t_mid): + speed d (t - t_mid) / D."""
    t = np.asarray(t, dtype=float)
    theta, omega, domega = theta0 + speed * t, np.full_like(t, speed), np.zeros_like(t)
    if ripple is not None:
        k, eps, ph = ripple
        arg = k * speed * t + ph
        theta = theta + eps / k * (np.sin(arg) - np.sin(ph))
        omega = omega + speed * eps * np.cos(arg)
        domega = domega - eps * k * speed ** 2 * np.sin(arg)
    if drift is not None:
        d, t_mid, span = drift
        theta = theta + speed * d * ((t - t_mid) ** 2 - t_mid ** 2) / (2 * span)
        omega = omega + speed * d * (t - t_mid) / span
        domega = domega + speed * d / span
    return theta, omega, domega


def drive_torque(rig, theta, omega, domega, factors=None, tip_viscous=0.0, details=False):
    """Shaft torque of Model 2 along a motion; factors: per-vane (tip, slot[, mass]) scale factors."""
    total = rig.rotor_inertia * domega + rig.bearing_torque
    per_vane, paradox = [], 0
    for i in range(rig.vanes):
        tf, sf, mf = (1.0, 1.0, 1.0) if factors is None else (tuple(factors[i]) + (1.0,))[:3]
        kin = vane_kinematics(rig, i, theta, omega, domega)
        r = vane_reactions(rig, kin, theta, omega, domega, tf, sf, tip_viscous, mf)
        total = total + r["tau"]
        paradox += r["paradox"]
        per_vane.append({**kin, **r})
    return (total, per_vane, paradox) if details else total


def closed_form_concentric(rig):
    """Spec §4: tau = sum mu_d m omega^2 r_G R, r_G = R - L/2."""
    return rig.vanes * rig.tip.dynamic * rig.mass * rig.speed ** 2 * (rig.radius - rig.length / 2) * rig.radius


def friction_power(rig, per_vane, omega):
    """Spec §4 power balance right-hand side: sum mu_h N |v_t| + mu_r (|F1| + |F2|) |s'|."""
    p = 0.0
    for v in per_vane:
        p = p + np.abs(rig.tip.mu(v["vt"])) * v["N"] * np.abs(v["vt"]) \
            + np.abs(rig.slot_friction.mu(v["sd"])) * (np.abs(v["F1"]) + np.abs(v["F2"])) * np.abs(v["sd"])
    return p


def to_toml(rig):
    """The spec §5 config of a rig (what diagnose is handed: the nominal pump)."""
    def fr(name, f):
        return (f"[friction.{name}]\nstatic = {f.static!r}\ndynamic = {f.dynamic!r}\n"
                f"v_static = {f.v_static!r}\nv_dynamic = {f.v_dynamic!r}\n")
    h = [f'name = "{rig.name}"', "[housing]", f'shape = "{rig.shape}"']
    h += [f"radius = {rig.radius!r}"] if rig.shape == "circle" else [f"a = {rig.a!r}", f"b = {rig.b!r}"]
    if rig.harmonics:
        h.append("harmonics = [" + ", ".join(f"[{k}, {A!r}, {g!r}]" for k, A, g in rig.harmonics) + "]")
    h += [f"center = [{rig.center[0]!r}, {rig.center[1]!r}]", f"angle = {rig.angle!r}", "[rotor]",
          f"radius = {rig.rotor_radius!r}", f"inertia = {rig.rotor_inertia!r}", f"vanes = {rig.vanes}",
          f"slot_radius = {rig.slot_radius!r}", f"slot_tilt = {rig.slot_tilt!r}",
          f"first_slot_angle = {rig.first_slot_angle!r}", "[vane]", f"length = {rig.length!r}",
          f"thickness = {rig.thickness!r}", f"mass = {rig.mass!r}"]
    if rig.vane_inertia is not None:
        h.append(f"inertia = {rig.vane_inertia!r}")
    h.append("tip_radius = 0.0")
    text = "\n".join(h) + "\n" + fr("housing", rig.tip)
    if rig.slot is not None:
        text += fr("slot", rig.slot)
    text += (f'[operation]\nmode = "speed"\nspeed = {rig.speed!r}\nangle = 0.0\n'
             f"bearing_torque = {rig.bearing_torque!r}\n")
    return text


RIGS = {
    # the report's COF rig (§14): concentric cylinder, 4 vanes, 5800 rpm
    "concentric4": Rig("concentric4"),
    # an eccentric circle by design (a real pump's layout), 5 vanes, other vane dimensions
    "eccentric5": Rig("eccentric5", radius=0.0245, center=(0.003, 0.0), vanes=5, slot_radius=0.0085, length=0.0125,
                      thickness=0.0025, mass=0.0010, speed=520.0, tip=Friction(0.17, 0.16),
                      slot=Friction(0.15, 0.14)),
    # the report's ellipse with 1, 3 and 4 vanes
    "ellipse1": Rig("ellipse1", shape="ellipse", vanes=1, speed=471.0, tip=Friction(0.18, 0.17)),
    "ellipse3": Rig("ellipse3", shape="ellipse", vanes=3, speed=471.0, tip=Friction(0.18, 0.17)),
    "ellipse4": Rig("ellipse4", shape="ellipse", vanes=4, speed=471.0, tip=Friction(0.18, 0.17)),
    # tilted slots, turned and off-centre ellipse with a measured 3-lobe, own vane inertia
    "tilted3": Rig("tilted3", shape="ellipse", a=0.0243, b=0.0218, harmonics=((3, 8e-6, 0.4),),
                   center=(2e-4, -1e-4), angle=0.25, vanes=3, slot_radius=0.0085, slot_tilt=0.18,
                   first_slot_angle=0.3, length=0.0118, thickness=0.0028, mass=0.0011,
                   vane_inertia=1.4e-8, speed=560.0, tip=Friction(0.23, 0.22, 2e-4, 2e-3),
                   slot=Friction(0.19, 0.18, 2e-4, 2e-3)),
}
