"""One vane, derived once as mechanics with SymPy (report §5.4): frames, points, velocities,
accelerations and virtual power (Kane's method).

The slot-wall reactions are brought into the equations with two *non-admissible* virtual
velocities (report §5.4.15-16): a lateral slide v_w of the vane along the slot normal w and a
relative tilt rate w_t about G. The admissible speeds are the rotor speed omega and the slide
speed sdot. Everything is symbolic in the slot angle phi, so N vanes are assembled later in CasADi
by evaluating the same expressions at phi_i.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import sympy as sp
from sympy.physics.vector import Point, ReferenceFrame, dynamicsymbols

# Input symbols of the derived expressions, by name (the CasADi assembly binds them).
SYMBOL_NAMES = (
    # rotor motion and slot
    "theta omega omegadot phi "
    # vane coordinate
    "s sdot sddot "
    # geometry and inertia
    "slot_radius slot_tilt rotor_radius L h m J rho "
    # housing contact point C and inward unit normal n at C (rotor-frame components)
    "Cx Cy nx ny "
    # forces: housing normal N, slot walls F1 F2 with contact sides sigma1 sigma2, slot bottom Fb
    "N F1 F2 sigma1 sigma2 Fb "
    # evaluated friction coefficients (odd in slip speed) and viscous tip coefficient
    "mu_h mu_r c_visc"
).split()


@dataclass(frozen=True)
class VaneMechanics:
    sym: dict  # name -> sympy Symbol
    points: dict  # point name -> (x, y) rotor-frame components
    slot_u: tuple  # slot direction u (rotor frame)
    slot_w: tuple  # slot side normal w (rotor frame)
    mouth_depth: sp.Expr  # l_m: distance from Ob to the slot mouth along u
    tip_slip: sp.Expr  # v_t: velocity of the vane's material point at C along t = z x n
    equations: dict  # 'slide', 'lateral', 'tilt' -> virtual-power residual (= 0)
    drive_torque_share: sp.Expr  # what this vane adds to the drive torque
    kinetic_energy: sp.Expr
    velocity_check: sp.Expr  # |v_G(from differentiation) - v_G(velocity field)|^2, must be 0


def _tidy(expr):
    """Expand and fold sin^2 + cos^2 of the slot angles (cheap; SymPy's trigsimp takes ~20 s)."""
    e = sp.expand(expr)
    for a in e.atoms(sp.sin):
        e = sp.expand(e.subs(a**2, 1 - sp.cos(a.args[0]) ** 2))
    return e


def _frames_and_points(S, th, sv) -> SimpleNamespace:
    """Rotor and slot frames and the vane's points (report Figure 2), positions from O."""
    Nf = ReferenceFrame("N")  # inertial
    Rf = Nf.orientnew("R", "Axis", [th, Nf.z])  # rotor
    Sf = Rf.orientnew("S", "Axis", [S["phi"] + S["slot_tilt"], Rf.z])  # slot (= vane: no tilt)
    u, w, z = Sf.x, Sf.y, Nf.z

    O = Point("O")
    O.set_vel(Nf, 0)
    phi, rb = S["phi"], S["slot_radius"]
    Ob = O.locatenew("Ob", rb * sp.cos(phi) * Rf.x + rb * sp.sin(phi) * Rf.y)
    # slot mouth: the point Ob + l_m u on the centre line at the rotor radius
    beta, Rr = S["slot_tilt"], S["rotor_radius"]
    l_m = -rb * sp.cos(beta) + sp.sqrt(Rr**2 - rb**2 * sp.sin(beta) ** 2)
    L, rho, h = S["L"], S["rho"], S["h"]
    A = Ob.locatenew("A", sv * u)
    G = Ob.locatenew("G", (sv + L / 2) * u)
    B = Ob.locatenew("B", (sv + L) * u)
    P = Ob.locatenew("P", (sv + L - rho) * u)
    Mo = Ob.locatenew("M", l_m * u)
    # Contact point and normal are given in rotor-frame components: every scalar equation is
    # rotation invariant, and in the rotor frame the vane geometry does not depend on theta, so the
    # expressions stay short (no products of sin(theta) with slot-angle terms).
    C = O.locatenew("C", S["Cx"] * Rf.x + S["Cy"] * Rf.y)
    n_hat = S["nx"] * Rf.x + S["ny"] * Rf.y
    Q1 = A.locatenew("Q1", -S["sigma1"] * h / 2 * w)
    Q2 = Mo.locatenew("Q2", -S["sigma2"] * h / 2 * w)
    return SimpleNamespace(Nf=Nf, Rf=Rf, u=u, w=w, z=z, O=O, Ob=Ob, A=A, G=G, B=B, P=P, Mo=Mo, C=C,
                           n_hat=n_hat, t_hat=z.cross(n_hat), Q1=Q1, Q2=Q2, l_m=l_m)


def _generalized_forces(S, g, plain, aG_vec, v_t, vane_velocity, speeds, vw, wt) -> dict:
    """Virtual power of every force along each speed (Kane): rotor, slide, lateral, tilt."""
    mu_h, mu_r = S["mu_h"], S["mu_r"]
    s1, s2 = S["sigma1"], S["sigma2"]
    F_housing = S["N"] * g.n_hat - (mu_h * S["N"] + S["c_visc"] * v_t) * g.t_hat
    F_slot1 = S["F1"] * g.w - mu_r * s1 * S["F1"] * g.u  # |F1| = sigma1 F1
    F_slot2 = S["F2"] * g.w - mu_r * s2 * S["F2"] * g.u
    F_bottom = S["Fb"] * g.u

    def rotor_velocity(X):
        return S["omega"] * g.z.cross(X.pos_from(g.O))

    # (point, force) pairs; reactions act on the rotor with opposite sign, same point
    on_vane = [(g.C, F_housing), (g.Q1, F_slot1), (g.Q2, F_slot2), (g.A, F_bottom), (g.G, -S["m"] * aG_vec)]
    on_rotor = [(g.Q1, -F_slot1), (g.Q2, -F_slot2), (g.A, -F_bottom)]
    vane_inertia_torque = -S["J"] * S["omegadot"] * g.z
    vane_angvel = (S["omega"] + wt) * g.z

    def generalized_force(speed):
        total = 0
        for X, F in on_vane:
            total += F.dot(vane_velocity(X).diff(speed, g.Nf))
        for X, F in on_rotor:
            total += F.dot(rotor_velocity(X).diff(speed, g.Nf))
        total += vane_inertia_torque.dot(vane_angvel.diff(speed, g.Nf))
        return _tidy((plain(total).subs({vw: 0, wt: 0})))

    return {name: generalized_force(sp_) for name, sp_ in zip(("rotor", "slide", "lateral", "tilt"), speeds)}


def derive_vane() -> VaneMechanics:
    S = {n: sp.Symbol(n, real=True) for n in SYMBOL_NAMES}
    t = sp.Symbol("t")
    th, sv = dynamicsymbols("theta_t s_t")
    g = _frames_and_points(S, th, sv)
    Rf, O, G = g.Rf, g.O, g.G

    # derivatives of the coordinates -> plain symbols
    to_plain = {
        th.diff(t, 2): S["omegadot"], sv.diff(t, 2): S["sddot"],
        th.diff(t): S["omega"], sv.diff(t): S["sdot"],
    }
    to_plain_q = {th: S["theta"], sv: S["s"]}

    def plain(expr):
        return sp.sympify(expr).subs(to_plain).subs(to_plain_q)

    # Velocity field of the vane: admissible speeds (omega, sdot), auxiliary speeds (vw, wt).
    vw, wt = sp.symbols("v_w w_t", real=True)
    speeds = (S["omega"], S["sdot"], vw, wt)

    def vane_velocity(X):
        rX = X.pos_from(O)
        return S["omega"] * g.z.cross(rX) + S["sdot"] * g.u + vw * g.w + wt * g.z.cross(X.pos_from(G))

    # acceleration of G by differentiation of its position (true kinematics)
    rG = G.pos_from(O)
    vG_true = rG.dt(g.Nf)
    aG = vG_true.dt(g.Nf)

    def comps(vec):
        return tuple(_tidy((plain(vec.express(Rf).dot(e)))) for e in (Rf.x, Rf.y))

    aG_xy = comps(aG)
    aG_vec = aG_xy[0] * Rf.x + aG_xy[1] * Rf.y
    vG_field = vane_velocity(G).subs({vw: 0, wt: 0})
    vcheck = comps(vG_true - vG_field)
    velocity_check = vcheck[0] ** 2 + vcheck[1] ** 2

    v_at_C = vane_velocity(g.C).subs({vw: 0, wt: 0})
    v_t = _tidy((plain(v_at_C.express(Rf).dot(g.t_hat))))
    gf = _generalized_forces(S, g, plain, aG_vec, v_t, vane_velocity, speeds, vw, wt)

    ke = _tidy((plain(sp.Rational(1, 2) * S["m"] * vG_true.dot(vG_true)
                                     + sp.Rational(1, 2) * S["J"] * S["omega"] ** 2)))

    pts = {"Ob": g.Ob, "A": g.A, "G": G, "B": g.B, "P": g.P, "M": g.Mo, "Q1": g.Q1, "Q2": g.Q2}
    return VaneMechanics(
        sym=S,
        points={k: comps(X.pos_from(O)) for k, X in pts.items()},
        slot_u=comps(g.u),
        slot_w=comps(g.w),
        mouth_depth=g.l_m,
        tip_slip=v_t,
        equations={k: gf[k] for k in ("slide", "lateral", "tilt")},
        # rotor virtual power: tau - tau_b - I_r omegadot + sum_i gf_rotor_i = 0
        drive_torque_share=-gf["rotor"],
        kinetic_energy=ke,
        velocity_check=velocity_check,
    )
