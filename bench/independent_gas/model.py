"""An independent implementation of the pump-down model (spec §1-4 geometry and Model 2, §8 gas,
ports, valves, leaks, booster and DC motor), written from /work/shared/spec/MODEL.md only.

It imports nothing from pumpsim/ or codegen/ (NumPy, SciPy and tomllib), so the bench logs it
writes test pumpsim against a second reading of the spec, not against its own equations.

Scope (rejected with a message otherwise): circular housing (any centre, angle), slots of any tilt,
rounded tips with tip_radius >= thickness/2 or point tips (tip_radius = 0), check exhaust valve,
constrained model (the tips stay on the housing).

Readings where the spec is silent (each a named choice below):
* The inlet and exhaust windows open into plenums of `ports.inlet_volume` / `ports.exhaust_volume`
  (gas with mass and temperature, no wall heat); the booster reaches the inlet plenum through its
  check valve, whose flow area is the hose orifice's opened in proportion to the excess pressure
  difference (one opening with the hose's C_d); the exhaust plenum reaches the atmosphere through
  the exhaust valve.
* A check valve's area grows in proportion to the excess over its cracking pressure difference and
  is full `full_open` (`check_full_open` for the booster's) above the cracking: the config keys'
  meaning in pumpsim's configuration reference (the spec names no key for it).
* Every orifice uses the isentropic law, linearised in the pressure difference for
  p_down/p_up > 0.999 (the exact law has an infinite slope at equal pressures).
* End-face leak: both end faces, each a gap `leak.end_gap` along the flank length exposed outside
  the rotor (zero where the flank is inside it).
* Gas on a vane: each cell's pressure on the vane surface it wets -- the exposed flank and the tip
  arc from the flank (or the rotor circle) up to the housing contact; the arc's resultant passes
  through the arc's centre. The slot bottom pushes out with p_slot h W. (The spec names the exposed
  face and the slot bottom; the tip is the same surface integral.)
* Wall heat exchange area of a cell: both end plates + (housing arc + rotor arc + the wetted
  flanks and tip arcs of its two vanes) x width.
* Motor friction: motor.friction x tanh(omega / 1 rad/s) (a constant torque is undefined at rest).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp

LINEAR_BELOW = 1.0e-3          # orifice law linear for 1 - p_down/p_up < this
WALL_TIP_ARCS = True           # the tip arcs count in a cell's heat-exchange area
TANH_SPEED = 1.0               # rad/s, motor friction's smoothing


def step(x, x0, h0, x1, h1):
    d = np.clip((x - x0) / (x1 - x0), 0.0, 1.0)
    return h0 + (h1 - h0) * d * d * (3.0 - 2.0 * d)


def mu_law(v, static, dynamic, vs, vd):
    """Spec §3 friction law, odd in v."""
    a = abs(v)
    if a <= vs:
        return step(v, -vs, -static, vs, static)
    if a <= vd:
        return math.copysign(step(a, vs, static, vd, dynamic), v)
    return math.copysign(dynamic, v)


@dataclass
class Pump:
    """Every number the model uses (SI), read from a spec §5/§8 config by `load`."""
    R: float
    center: tuple
    psi: float
    Rr: float
    Ir: float
    N: int
    rb: float
    beta: float
    phi0: float
    W: float
    L: float
    h: float
    m: float
    J: float
    rho: float
    slot_pressure: object
    fr_h: tuple
    fr_s: tuple
    gas_R: float = 287.05
    gamma: float = 1.4
    T0: float = 293.15
    T_wall: float = 293.15
    h_wall: float = 0.0
    p_atm: float = 101325.0
    inlet: tuple = (0.0, 0.0)
    exhaust: tuple = (0.0, 0.0)
    inlet_width: float = 0.0
    exhaust_width: float = 0.0
    cd_port: float = 0.7
    cd_hose: float = 0.7
    cd_valve: float = 0.7
    cd_leak: float = 0.7
    V_in: float = 2.0e-6
    V_ex: float = 2.0e-7
    hose_area: float = 0.0
    check_crack: float = 0.0
    check_full: float = 500.0       # excess over check_crack for the full area
    valve_area: float = 0.0
    valve_crack: float = 0.0
    valve_full: float = 2000.0      # excess over valve_crack for the full area
    tip_gap: float = 0.0
    end_gap: float = 0.0
    Vb: float = 4.0e-3
    pb0: float = 101325.0
    target: float = 0.0
    booster_leak: float = 0.0
    voltage: float = 12.0
    Rm: float = 0.25
    Lm: float = 1.0e-4
    km: float = 0.025
    motor_friction: float = 0.0
    Im: float = 0.0
    bearing: float = 0.0
    # hidden changes a bench log may carry (the generator sets them; a config never does)
    supply_resistance: float = 0.0
    heating: float = 0.0            # relative resistance rise per second of run
    # pumpsim's readings where the spec leaves room (off: this model's own; for measuring the gap)
    isothermal_plenums: bool = False  # inlet and exhaust plenums held at T0
    pocket_in_cell: bool = False      # the slot mouth beside a retracted tip counts as cell gas
    extra: dict = field(default_factory=dict)

    def with_mu(self, mu):
        """`mu` as pumpsim names it: the dynamic COF, static scaled by the configured ratio, the
        slot law tied to the housing law's scale."""
        f = mu / self.fr_h[1]
        return replace(self, fr_h=(self.fr_h[0] * f, mu, *self.fr_h[2:]),
                       fr_s=(self.fr_s[0] * f, self.fr_s[1] * f, *self.fr_s[2:]))


def _friction(t):
    return (t["static"], t["dynamic"], t.get("v_static", 1.0e-4), t.get("v_dynamic", 1.0e-3))


def load(path) -> Pump:
    with open(path, "rb") as f:
        c = tomllib.load(f)
    ho, ro, va = c["housing"], c["rotor"], c["vane"]
    if ho.get("shape", "circle") != "circle" or ho.get("harmonics"):
        raise ValueError("independent model: only a plain circular housing (housing.shape = circle)")
    vt = c.get("valve", {})
    if vt.get("type", "check") != "check":
        raise ValueError("independent model: only valve.type = check")
    L, h, m = va["length"], va["thickness"], va["mass"]
    rho = va.get("tip_radius", 0.0)
    if 0.0 < rho < h / 2:
        raise ValueError("independent model: vane.tip_radius must be 0 or >= thickness/2")
    g, pt, lk, bo, mo = (c.get(k, {}) for k in ("gas", "ports", "leak", "booster", "motor"))
    cd = pt.get("discharge_coefficient", 0.7)
    fr_h = _friction(c["friction"]["housing"])
    p_atm = g.get("atmosphere", 101325.0)
    T0 = g.get("temperature", 293.15)
    return Pump(
        R=ho["radius"], center=tuple(ho.get("center", (0.0, 0.0))), psi=ho.get("angle", 0.0),
        Rr=ro["radius"], Ir=ro["inertia"], N=ro["vanes"], rb=ro["slot_radius"],
        beta=ro.get("slot_tilt", 0.0), phi0=ro.get("first_slot_angle", 0.0), W=ro["width"],
        L=L, h=h, m=m, J=va.get("inertia", m * (L * L + h * h) / 12.0), rho=rho,
        slot_pressure=va.get("slot_pressure", "exhaust"), fr_h=fr_h,
        fr_s=_friction(c["friction"].get("slot", c["friction"]["housing"])),
        gas_R=g.get("gas_constant", 287.05), gamma=g.get("gamma", 1.4), T0=T0,
        T_wall=g.get("wall_temperature", T0), h_wall=g.get("heat_transfer", 0.0), p_atm=p_atm,
        inlet=tuple(pt["inlet"]), exhaust=tuple(pt["exhaust"]),
        inlet_width=pt.get("inlet_width", pt.get("width")),
        exhaust_width=pt.get("exhaust_width", pt.get("width")), cd_port=cd,
        cd_hose=pt.get("hose_discharge_coefficient", cd), cd_valve=vt.get("discharge_coefficient", cd),
        cd_leak=lk.get("discharge_coefficient", cd), V_in=pt.get("inlet_volume", 2.0e-6),
        V_ex=pt.get("exhaust_volume", 2.0e-7), hose_area=math.pi * pt.get("hose_diameter", 4e-3) ** 2 / 4,
        check_crack=pt.get("check_cracking", 0.0), check_full=pt.get("check_full_open", 500.0),
        valve_area=vt["area"], valve_crack=vt.get("cracking", 0.0), valve_full=vt.get("full_open", 2000.0),
        tip_gap=lk.get("tip_gap", 0.0), end_gap=lk.get("end_gap", 0.0), Vb=bo["volume"],
        pb0=bo.get("pressure", p_atm), target=bo.get("target", 0.0), booster_leak=bo.get("leak", 0.0),
        voltage=mo["voltage"], Rm=mo["resistance"], Lm=mo["inductance"], km=mo["constant"],
        motor_friction=mo.get("friction", 0.0), Im=mo.get("inertia", 0.0),
        bearing=c.get("operation", {}).get("bearing_torque", 0.0))


# ---------------------------------------------------------------- geometry (rotor frame)

def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _zx(a):
    return np.array([-a[1], a[0]])


def _rot(t, v):
    c, s = math.cos(t), math.sin(t)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _arc_green(c, r, t1, t2):
    """(1/2) closed integral of x dy - y dx along the circle (c, r) from angle t1 to t2."""
    return 0.5 * (r * r * (t2 - t1) + c[0] * r * (math.sin(t2) - math.sin(t1))
                  - c[1] * r * (math.cos(t2) - math.cos(t1)))


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class Vane:
    """Vane i at rotor angle theta: slot frame, the tip-arc centre's distance ell(theta) from the
    slot bottom (P = Ob + ell u on the circle of radius R - rho about the housing centre)."""

    def __init__(self, pump: Pump, i: int, theta: float):
        p = pump
        phi = p.phi0 + 2 * math.pi * i / p.N
        self.Ob = p.rb * np.array([math.cos(phi), math.sin(phi)])
        self.u = np.array([math.cos(phi + p.beta), math.sin(phi + p.beta)])
        self.w = _zx(self.u)
        self.C = _rot(-theta, np.array(p.center))           # housing centre, rotor frame
        d = self.Ob - self.C
        b, c = self.u @ d, d @ d - (p.R - p.rho) ** 2
        self.ell = -b + math.sqrt(b * b - c)
        self.P = self.Ob + self.ell * self.u
        e = (self.P - self.C) / np.linalg.norm(self.P - self.C)
        self.contact = self.C + p.R * e
        self.n = -e                                          # inward housing normal
        bm = self.Ob @ self.u
        self.ell_mouth = -bm + math.sqrt(bm * bm - (self.Ob @ self.Ob - p.Rr ** 2))
        self.p = p

    def side(self, sgn):
        """Boundary from the rotor circle to the contact point on the face sgn*w: list of pieces
        ('line', a, b) / ('arc', centre, r, t1, t2), and the rotor-circle point."""
        p = self.p
        off = self.Ob + sgn * p.h / 2 * self.w
        t_rot = _flank_meets_rotor(p, self.Ob, self.u, self.w, sgn)
        if p.rho == 0.0:
            corner = off + (self.ell) * self.u                        # ell = s + L for a point tip
            x0 = off + t_rot * self.u
            return [("line", x0, corner), ("line", corner, self.contact)], x0
        top = math.sqrt(p.rho ** 2 - p.h ** 2 / 4)                  # flank-arc junction above P
        junction = off + (self.ell + top) * self.u
        tc = math.atan2(*(self.contact - self.P)[::-1])
        if t_rot <= self.ell + top or p.pocket_in_cell:
            x0 = off + t_rot * self.u
            tj = math.atan2(*(junction - self.P)[::-1])
            return [("line", x0, junction), ("arc", self.P, p.rho, tj, tj + _wrap(tc - tj))], x0
        x0 = _circle_cut(self.P, p.rho, p.Rr, self.w * sgn)          # cap crosses the rotor circle
        t0 = math.atan2(*(x0 - self.P)[::-1])
        return [("arc", self.P, p.rho, t0, t0 + _wrap(tc - t0))], x0

    def flank_out(self):
        """Length of the vane's flanks exposed outside the rotor, the mean of its two sides (each
        from where that side meets the rotor circle; zero where it is inside)."""
        p = self.p
        top = math.sqrt(p.rho ** 2 - p.h ** 2 / 4) if p.rho > 0 else 0.0
        return 0.5 * sum(max(0.0, self.ell + top - _flank_meets_rotor(p, self.Ob, self.u, self.w, sg))
                         for sg in (1.0, -1.0))

    def s(self):
        return self.ell - (self.p.L - self.p.rho)


def _flank_meets_rotor(p, Ob, u, w, sgn):
    """Distance along u from Ob + sgn h/2 w to where the flank on the side sgn w meets the rotor
    circle."""
    off = Ob + sgn * p.h / 2 * w
    bo = off @ u
    return -bo + math.sqrt(bo * bo - (off @ off - p.Rr ** 2))


def _circle_cut(P, rho, Rr, wdir):
    """The point of |x| = Rr on the circle (P, rho) on the side wdir of P."""
    d = np.linalg.norm(P)
    a = (Rr * Rr - rho * rho + d * d) / (2 * d)
    hh = math.sqrt(max(Rr * Rr - a * a, 0.0))
    e = P / d
    base = a * e
    cands = [base + hh * _zx(e), base - hh * _zx(e)]
    return max(cands, key=lambda x: (x - P) @ wdir)


def _path_green(pieces, reverse=False):
    tot = 0.0
    for pc in pieces:
        if pc[0] == "line":
            a, b = pc[1], pc[2]
            tot += 0.5 * _cross(a, b)
        else:
            tot += _arc_green(pc[1], pc[2], pc[3], pc[4])
    return -tot if reverse else tot


def _path_length(pieces):
    return sum(np.linalg.norm(pc[2] - pc[1]) if pc[0] == "line" else pc[2] * abs(pc[4] - pc[3]) * WALL_TIP_ARCS
               for pc in pieces)


def cells(pump: Pump, theta: float, vanes=None):
    """Per cell i (between vane i and i+1): volume, wall area, housing-arc polar interval
    (housing frame, start and CCW length)."""
    p = pump
    vanes = vanes or [Vane(p, i, theta) for i in range(p.N)]
    out = []
    for i in range(p.N):
        a, b = vanes[i], vanes[(i + 1) % p.N]
        lead, xa = a.side(+1)
        trail, xb = b.side(-1)
        ta = math.atan2(*(a.contact - a.C)[::-1])
        dt_h = (math.atan2(*(b.contact - b.C)[::-1]) - ta) % (2 * math.pi)
        r1, r2 = math.atan2(xb[1], xb[0]), math.atan2(xa[1], xa[0])
        dt_r = (r1 - r2) % (2 * math.pi)
        area = (_path_green(lead) + _arc_green(a.C, p.R, ta, ta + dt_h)
                - _path_green(trail) + _arc_green(np.zeros(2), p.Rr, r1, r1 - dt_r))
        wall = 2 * area + p.W * (p.R * dt_h + p.Rr * dt_r + _path_length(lead) + _path_length(trail))
        # housing polar angle in the housing frame: rotor-frame angle about C plus theta, minus psi
        out.append((area * p.W, wall, ta + theta - p.psi, dt_h))
    return out


def arc_overlap(a, la, s, e):
    """Length (rad) of the overlap of the CCW arc [a, a+la] with the window [s, e]."""
    lp = (e - s) % (2 * math.pi)
    s0 = a + (s - a) % (2 * math.pi)
    tot = 0.0
    for st in (s0, s0 - 2 * math.pi):
        tot += max(0.0, min(a + la, st + lp) - max(a, st))
    return tot


# ---------------------------------------------------------------- flows

def orifice(p, cdA, p1, T1, p2, T2):
    """Signed mass flow 1 -> 2 through an opening of effective area cdA (spec §8 orifice law)."""
    if cdA <= 0.0 or p1 == p2:
        return 0.0
    if p1 < p2:
        return -orifice(p, cdA, p2, T2, p1, T1)
    g = p.gamma
    crit = (2 / (g + 1)) ** (g / (g - 1))

    def psi(r):
        return math.sqrt(max(r ** (2 / g) - r ** ((g + 1) / g), 0.0) * 2 * g / (g - 1))

    r = p2 / p1
    if r <= crit:
        f = psi(crit)
    elif r < 1 - LINEAR_BELOW:
        f = psi(r)
    else:
        f = psi(1 - LINEAR_BELOW) * (1 - r) / LINEAR_BELOW
    return cdA * p1 * f / math.sqrt(p.gas_R * T1)


def booster_leak_flow(p, pb):
    """booster.leak is the flow at the full atmospheric difference; the orifice law sets its shape."""
    if p.booster_leak <= 0:
        return 0.0
    return p.booster_leak * orifice(p, 1.0, p.p_atm, p.T0, pb, p.T0) / orifice(p, 1.0, p.p_atm, p.T0, 0.0, p.T0)


# ---------------------------------------------------------------- vane mechanics (Model 2)

class Vanes:
    """All N vanes at rotor angle theta, each in its own slot frame (Ob = r_b e_x, u at the tilt), as
    arrays over the vanes; ell = |P - Ob| with P the tip-arc centre on the circle R - rho about
    the housing centre, and its theta-derivatives in closed form."""

    def __init__(self, p: Pump, theta: float):
        phi = p.phi0 + 2 * np.pi * np.arange(p.N) / p.N
        a = -(theta + phi)
        cx, cy = p.center
        C = np.stack([np.cos(a) * cx - np.sin(a) * cy, np.sin(a) * cx + np.cos(a) * cy], 1)
        u = np.array([math.cos(p.beta), math.sin(p.beta)])
        w = np.array([-u[1], u[0]])
        Ob = np.array([p.rb, 0.0])
        d = Ob - C
        zc = np.stack([-C[:, 1], C[:, 0]], 1)
        b, c = d @ u, np.sum(d * d, 1) - (p.R - p.rho) ** 2
        b1, c1 = zc @ u, 2 * np.sum(d * zc, 1)
        b2, c2 = C @ u, 2 * (np.sum(C * C, 1) + np.sum(d * C, 1))
        D = b * b - c
        sq = np.sqrt(D)
        D1, D2 = 2 * b * b1 - c1, 2 * b1 * b1 + 2 * b * b2 - c2
        self.ell = -b + sq
        self.l1 = -b1 + D1 / (2 * sq)
        self.l2 = -b2 + D2 / (2 * sq) - D1 * D1 / (4 * D * sq)
        P = Ob + self.ell[:, None] * u
        e = (P - C) / np.linalg.norm(P - C, axis=1)[:, None]
        self.contact = C + p.R * e
        self.n = -e
        bm = Ob @ u
        self.ell_mouth = -bm + math.sqrt(bm * bm - (Ob @ Ob - p.Rr ** 2))
        top = math.sqrt(p.rho ** 2 - p.h ** 2 / 4) if p.rho > 0 else 0.0
        # the mean of the two flanks' lengths outside the rotor (each from its own rotor crossing)
        self.flank_out = 0.5 * sum(np.maximum(0.0, self.ell + top - _flank_meets_rotor(p, Ob, u, w, sg))
                                   for sg in (1.0, -1.0))
        self.s = self.ell - (p.L - p.rho)
        self.u, self.w, self.Ob = u, w, Ob


def _cross_rows(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def gas_loads(p: Pump, v: Vanes, p_cell, G):
    """Force (N, 2) and moment about G (N,) of the cells' pressures on each vane's wetted surface:
    cell k on the +w side of vane k, cell k-1 on the -w side. A uniform pressure on a path from a
    to b (the vane on its inner side) gives -side p W z x (b - a)."""
    F = np.zeros((p.N, 2))
    M = np.zeros(p.N)
    top = math.sqrt(p.rho ** 2 - p.h ** 2 / 4) if p.rho > 0 else 0.0
    for side, pc in ((1.0, p_cell), (-1.0, np.roll(p_cell, 1))):
        off = v.Ob + side * p.h / 2 * v.w
        t_rot = _flank_meets_rotor(p, v.Ob, v.u, v.w, side)
        for k in range(p.N):
            P = v.Ob + v.ell[k] * v.u
            end = v.contact[k]
            if p.rho == 0.0:
                pieces = [(off + t_rot * v.u, off + v.ell[k] * v.u, None), (off + v.ell[k] * v.u, end, None)]
            elif t_rot <= v.ell[k] + top or p.pocket_in_cell:
                j = off + (v.ell[k] + top) * v.u
                pieces = [(off + t_rot * v.u, j, None), (j, end, P)]
            else:
                pieces = [(_circle_cut(P, p.rho, p.Rr, side * v.w), end, P)]
            for a, b, centre in pieces:
                f = -side * pc[k] * p.W * _zx(b - a)
                at = (a + b) / 2 if centre is None else centre
                F[k] += f
                M[k] += _cross(at - G[k], f)
    return F, M


def mechanics(p: Pump, v: Vanes, omega, p_cell, p_slot, drive, signs):
    """The 3N vane reactions (N, F1, F2 per vane) and omega' (spec §3 Model 2 with §8 gas loads):
    per vane a 3x3 system linear in omega' once the slot contact sides are fixed, closed by the
    rotor equation; the sides are iterated to consistency. drive: k i - motor friction - bearing.
    Returns omega', the signs, the reactions (N, 3)."""
    u, w, Ob = v.u, v.w, v.Ob
    sdot = v.l1 * omega
    G = Ob + (v.s + p.L / 2)[:, None] * u
    zG = np.stack([-G[:, 1], G[:, 0]], 1)
    a0 = (v.l2 * omega ** 2)[:, None] * u + (2 * omega ** 2 * v.l1)[:, None] * w - omega ** 2 * G
    a1 = v.l1[:, None] * u + zG
    t_hat = np.stack([-v.n[:, 1], v.n[:, 0]], 1)
    zc = np.stack([-v.contact[:, 1], v.contact[:, 0]], 1)
    vt = np.sum((omega * zc + sdot[:, None] * u) * t_hat, 1)
    mu_t = np.array([mu_law(x, *p.fr_h) for x in vt])
    mu_r = np.array([mu_law(x, *p.fr_s) for x in sdot])
    Fk, Mk = gas_loads(p, v, p_cell, G)
    Fk = Fk + p_slot * p.h * p.W * u                          # the slot bottom pushes out
    sig = np.array(signs, float)
    for _ in range(8):
        d0 = v.n - mu_t[:, None] * t_hat
        d1 = w - (mu_r * sig[:, 0])[:, None] * u
        d2 = w - (mu_r * sig[:, 1])[:, None] * u
        p0 = v.contact
        p1 = Ob + v.s[:, None] * u - (sig[:, 0] * p.h / 2)[:, None] * w
        p2 = Ob + v.ell_mouth * u - (sig[:, 1] * p.h / 2)[:, None] * w
        M = np.empty((p.N, 3, 3))
        for j, (dj, pj) in enumerate(((d0, p0), (d1, p1), (d2, p2))):
            M[:, 0, j], M[:, 1, j] = dj[:, 0], dj[:, 1]
            M[:, 2, j] = _cross_rows(pj - G, dj)
        r0 = np.stack([p.m * a0[:, 0] - Fk[:, 0], p.m * a0[:, 1] - Fk[:, 1], -Mk], 1)
        r1 = np.stack([p.m * a1[:, 0], p.m * a1[:, 1], np.full(p.N, p.J)], 1)
        X = np.linalg.solve(M, np.stack([r0, r1], 2))        # x = X0 + omega' X1
        # the rotor gets minus the slot-wall forces and the slot gas's push on the slot bottom
        c1, c2 = _cross_rows(p1, d1), _cross_rows(p2, d2)
        gas = p.N * _cross(Ob, -p_slot * p.h * p.W * u)
        num = drive + gas - np.sum(c1 * X[:, 1, 0] + c2 * X[:, 2, 0])
        den = p.Ir + p.Im + np.sum(c1 * X[:, 1, 1] + c2 * X[:, 2, 1])
        dw = num / den
        x = X[:, :, 0] + dw * X[:, :, 1]
        new = np.where(x[:, 1:] >= 0, 1.0, -1.0)
        if np.array_equal(new, sig):
            break
        sig = new
    return dw, [tuple(s) for s in sig], x


# ---------------------------------------------------------------- the pump-down ODE

class CellTable:
    """Cell 0's volume, wall area and housing arc tabulated over a revolution (periodic cubic
    splines); cell i at theta is cell 0 at theta + 2 pi i / N (equal slots)."""

    def __init__(self, p: Pump, n=4096):
        from scipy.interpolate import CubicSpline
        th = np.linspace(0.0, 2 * np.pi, n + 1)
        rows = np.array([cells(p, t)[0] for t in th[:-1]])
        rows[:, 2] = np.unwrap(rows[:, 2]) - th[:-1]       # arc start minus theta: periodic
        rows = np.vstack([rows, rows[:1]])
        self.spline = CubicSpline(th, rows, bc_type="periodic")
        self.dspline = self.spline.derivative()
        self.N = p.N

    def __call__(self, theta):
        x = (theta + 2 * np.pi * np.arange(self.N) / self.N) % (2 * np.pi)
        r = self.spline(x)
        return r[:, 0], self.dspline(x)[:, 0], r[:, 1], r[:, 2] + x, r[:, 3]


def arc_overlaps(a, la, s, e):
    """Vector form of arc_overlap over the cells."""
    lp = (e - s) % (2 * np.pi)
    s0 = a + (s - a) % (2 * np.pi)
    tot = np.zeros_like(a)
    for st in (s0, s0 - 2 * np.pi):
        tot += np.maximum(0.0, np.minimum(a + la, st + lp) - np.maximum(a, st))
    return tot


class PumpDown:
    """State: cell masses and temperatures (N each), inlet plenum mass, temperature, exhaust plenum
    mass, temperature, booster pressure, current, speed, angle."""

    def __init__(self, pump: Pump, voltage, source_resistance=0.0, table=None):
        self.p = pump
        self.voltage = voltage            # supply voltage before the source resistance, f(t)
        self.r_src = source_resistance    # the logged voltage is taken after it
        self.signs = [(1.0, 1.0)] * pump.N
        self.nfev = 0
        self.table = table or CellTable(pump)

    def y0(self):
        p = self.p
        V = self.table(0.0)[0]
        return np.concatenate([p.p_atm * V / (p.gas_R * p.T0), np.full(p.N, p.T0),
                               [p.pb0 * p.V_in / (p.gas_R * p.T0), p.T0,
                                p.p_atm * p.V_ex / (p.gas_R * p.T0), p.T0, p.pb0, 0.0, 0.0, 0.0]])

    def resistance(self, t):
        return self.p.Rm * (1 + self.p.heating * t) + self.p.supply_resistance

    def flows(self, y, V, a0, la, flank_out):
        """Mass flow and inflow enthalpy per node (cells 0..N-1, inlet plenum, exhaust plenum), the
        cell pressures, plenum pressures and the booster's net outflow."""
        p, N = self.p, self.p.N
        m_c, T_c = y[:N], y[N:2 * N]
        m_in, T_in, m_ex, T_ex, pb = y[2 * N:2 * N + 5]
        if p.isothermal_plenums:
            T_in = T_ex = p.T0
        pc = m_c * p.gas_R * T_c / V
        p_in, p_ex = m_in * p.gas_R * T_in / p.V_in, m_ex * p.gas_R * T_ex / p.V_ex
        P = list(pc) + [p_in, p_ex]
        T = list(T_c) + [T_in, T_ex]
        dm = np.zeros(N + 2)
        dh = np.zeros(N + 2)
        cp = p.gamma * p.gas_R / (p.gamma - 1)

        def link(a, b, cdA):
            f = orifice(p, cdA, P[a], T[a], P[b], T[b])
            tu = T[a] if f > 0 else T[b]
            dm[a] -= f
            dm[b] += f
            dh[a] -= f * cp * tu
            dh[b] += f * cp * tu

        a_in = p.cd_port * p.R * arc_overlaps(a0, la, *p.inlet) * p.inlet_width
        a_ex = p.cd_port * p.R * arc_overlaps(a0, la, *p.exhaust) * p.exhaust_width
        for i in range(N):
            link(N, i, a_in[i])
            link(i, N + 1, a_ex[i])
            # leaks across vane i: between cell i-1 and cell i
            link((i - 1) % N, i, p.cd_leak * (p.tip_gap * p.W + 2 * p.end_gap * flank_out[i]))
        # booster -> inlet plenum through the check valve (the hose area opened in proportion)
        open_in = min(max((pb - p_in - p.check_crack) / p.check_full, 0.0), 1.0)
        f_b = max(orifice(p, p.cd_hose * p.hose_area * open_in, pb, p.T0, p_in, T_in), 0.0)
        dm[N] += f_b
        dh[N] += f_b * cp * p.T0
        open_ex = min(max((p_ex - p.p_atm - p.valve_crack) / p.valve_full, 0.0), 1.0)
        f_v = max(orifice(p, p.cd_valve * p.valve_area * open_ex, p_ex, T_ex, p.p_atm, p.T0), 0.0)
        dm[N + 1] -= f_v
        dh[N + 1] -= f_v * cp * T_ex
        return dm, dh, pc, p_in, p_ex, f_b - booster_leak_flow(p, pb)

    def rhs(self, t, y):
        self.nfev += 1
        p, N = self.p, self.p.N
        i_m, omega, theta = y[-3:]
        V, dV, wall, a0, la = self.table(theta)
        vanes = Vanes(p, theta)
        dm, dh, pc, p_in, p_ex, f_booster = self.flows(y, V, a0, la, vanes.flank_out)
        cv = p.gas_R / (p.gamma - 1)
        masses = np.concatenate([y[:N], [y[2 * N], y[2 * N + 2]]])
        temps = np.concatenate([y[N:2 * N], [y[2 * N + 1], y[2 * N + 3]]])
        work = np.concatenate([pc * dV * omega, [0.0, 0.0]])
        heat = np.concatenate([p.h_wall * wall * (p.T_wall - y[N:2 * N]), [0.0, 0.0]])
        dT = (dh - cv * temps * dm - work + heat) / (masses * cv)
        out = np.empty_like(y)
        out[:N], out[N:2 * N] = dm[:N], dT[:N]
        out[2 * N:2 * N + 4] = dm[N], dT[N], dm[N + 1], dT[N + 1]
        if p.isothermal_plenums:
            out[2 * N + 1] = out[2 * N + 3] = 0.0
        out[2 * N + 4] = -f_booster * p.gas_R * p.T0 / p.Vb
        out[-3] = (self.voltage(t) - (self.resistance(t) + self.r_src) * i_m - p.km * omega) / p.Lm
        slot = {"exhaust": p_ex, "inlet": p_in, "atmosphere": p.p_atm}.get(p.slot_pressure, p.slot_pressure)
        drive = p.km * i_m - p.motor_friction * math.tanh(omega / TANH_SPEED) - p.bearing
        out[-2], self.signs, _ = mechanics(p, vanes, omega, pc, float(slot), drive, self.signs)
        out[-1] = omega
        return out

    def run(self, t_eval, rtol=1e-7, method="BDF"):
        p, N = self.p, self.p.N
        y0 = self.y0()
        scale = np.abs(y0)
        scale[N:2 * N] = p.T0
        scale[2 * N + 1] = scale[2 * N + 3] = p.T0
        scale[-3:] = [10.0, 100.0, 1.0]
        sol = solve_ivp(self.rhs, (t_eval[0], t_eval[-1]), y0, method=method, t_eval=t_eval,
                        rtol=rtol, atol=rtol * scale)
        if not sol.success:
            raise RuntimeError(f"independent model: integration failed at t = {sol.t[-1]:.4g} s: {sol.message}")
        i_m, omega, pb = sol.y[-3], sol.y[-2], sol.y[2 * N + 4]
        v_log = np.array([self.voltage(t) for t in sol.t]) - self.r_src * i_m
        return {"time": sol.t, "voltage": v_log, "current": i_m, "booster_pressure": pb, "speed": omega,
                "nfev": self.nfev, "y": sol.y}
