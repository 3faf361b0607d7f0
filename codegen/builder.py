"""The shared model builder: the pump model's building blocks in CasADi, from the one-vane
mechanics (SymPy is used only here).

Each model variant has its own builder module over this one (constrained_model, contact_model,
pneumatic_model, pneumatic_contact_model); each returns a frozen `BuiltModel`: named CasADi
functions, each with the input and output names the contract declares
(pumpsim/model_spec/outputs.py), that `codegen.build` compiles to one shared library per variant.

Constrained model (Model 2) per vane, given the rotor motion (theta, omega, omegadot):
1. position: the tip-arc centre P lies at distance rho from the housing along its normal,
   Phi(theta, s, alpha) = P(theta, s) - C(alpha) - rho n(alpha) = 0, solved for (s, alpha) by a ray
   intersection guess and unrolled Newton steps;
2. velocity and acceleration from Phi_q qdot = 0 and Phi_q qddot + (Phi_q qdot)_q qdot = 0;
3. dynamics: for each contact-side set (sigma1, sigma2) the virtual-power equations are linear in
   (N, F1, F2); the consistent set (sign F_j = sigma_j) is selected, and the number of consistent
   sets is returned so the runtime can report a friction paradox.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

from pumpsim.model_spec import laws
from pumpsim.model_spec.outputs import VANE_OUTPUTS, check_signature
from pumpsim.model_spec.parameters import Parameter, Structure, friction_args, layout

from .housing import base_ray, derive_housing, parameter_names
from .mechanics import SYMBOL_NAMES, derive_vane
from .to_casadi import lambdify_casadi

# Scalar Newton steps in alpha from the ray/ellipse guess. Without harmonics the guess is exact for
# rho = 0 and O(rho * curvature change) off otherwise, so two quadratic steps reach rounding; with
# harmonics the guess is off by ~A_k/r and four steps are used. Every sample's residual is returned
# and checked by the runtime, so a non-converged solve is reported, never used.
NEWTON_ITERATIONS = {"plain": 2, "harmonics": 4}
FORWARD_ITERATIONS = 4  # Newton on omegadot; the torque is piecewise affine in omegadot
SIGN_SETS = ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0))
CONSISTENCY_TOL = 1e-9  # relative: a contact-side set is consistent if sign errors < tol * |forces|

def rotor_torque(Ir, tb, omegadot, shares):
    """The drive torque the rotor equation needs at omegadot: I_r omegadot + bearing torque + the
    vanes' shares (both models)."""
    return Ir * omegadot + tb + ca.sum2(shares)


def newton_omegadot(required, Ir, tau):
    """Torque drive: omegadot with required(omegadot) = tau by Newton (both models). required(w)
    -> (drive torque, the vanes' slopes d share / d omegadot): the torque is piecewise affine in
    omegadot and each vane returns its slope on the selected branch, so no nested AD is needed."""
    w = ca.MX(0.0)
    for _ in range(FORWARD_ITERATIONS):
        rt, slopes = required(w)
        w = w - (rt - tau) / (Ir + ca.sum2(slopes))
    return w


def _solve3(A, b):
    """3x3 linear solve by Cramer's rule (fewer instructions than a symbolic QR; the systems here
    are well conditioned: rows are force balances with unit coefficients on F1, F2)."""
    def det(M):
        return (M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1])
                - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
                + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]))
    D = det(A)
    cols = []
    for j in range(3):
        Aj = ca.horzcat(*[b if k == j else A[:, k] for k in range(3)])
        cols.append(det(Aj) / D)
    return ca.vertcat(*cols)


CASADI_OPS = laws.make_ops(ca.fmin, ca.fmax, ca.fabs, ca.sign, ca.sqrt, ca.power, ca.if_else)


@dataclass(frozen=True)
class BuiltModel:
    structure: Structure
    parameters: tuple[Parameter, ...]
    functions: dict  # name -> casadi.Function (exported, compiled)

    def __post_init__(self):
        for name, f in self.functions.items():  # the contract decides names and shapes
            check_signature(self.structure.model, name, f.name_in(), f.name_out())


class Builder:
    """The symbolic building blocks every model variant shares: the parameter vector, the one-vane
    mechanics, the housing curve, friction laws, Model 2's position solve and vane function, and
    the contact-side selection; one subclass or function per variant assembles its exported
    functions from them."""

    def __init__(self, structure: Structure, params=None):
        """params: the variant's parameter layout (default: the mechanical model's, layout())."""
        self.st = structure
        self.params = layout(structure) if params is None else params
        self.p = ca.SX.sym("p", len(self.params))
        self.P = {q.name: self.p[i] for i, q in enumerate(self.params)}
        self._mechanics()
        self._housing()

    # -- symbolic building blocks --------------------------------------------------------------
    def _mechanics(self):
        mech = derive_vane()
        self.mech_names = ["Ob", "A", "G", "B", "P", "M"]
        exprs = []
        for k in self.mech_names:
            exprs += list(mech.points[k])
        exprs += list(mech.slot_u) + list(mech.slot_w)
        exprs += [mech.mouth_depth, mech.tip_slip, mech.equations["slide"],
                  mech.equations["lateral"], mech.equations["tilt"], mech.drive_torque_share,
                  mech.kinetic_energy]
        sx_in = [ca.SX.sym(n) for n in SYMBOL_NAMES]
        out = lambdify_casadi([mech.sym[n] for n in SYMBOL_NAMES], exprs)(*sx_in)
        self.mech_fun = ca.Function("vane_mechanics", [ca.vertcat(*sx_in)], [ca.vertcat(*out)])

    def mech(self, **values):
        """Evaluate the one-vane mechanics; unset inputs are zero."""
        vec = ca.vertcat(*[values.get(n, 0.0) for n in SYMBOL_NAMES])
        out = self.mech_fun(vec)
        res, i = {}, 0
        for k in self.mech_names:
            res[k] = out[i:i + 2]
            i += 2
        res["u"], res["w"] = out[i:i + 2], out[i + 2:i + 4]
        i += 4
        for k in ("mouth_depth", "tip_slip", "eq_slide", "eq_lateral", "eq_tilt", "torque_share",
                  "kinetic_energy"):
            res[k] = out[i]
            i += 1
        return res

    def geometry(self):
        P = self.P
        return dict(slot_radius=P["rotor.slot_radius"], slot_tilt=P["rotor.slot_tilt"],
                    rotor_radius=P["rotor.radius"], L=P["vane.length"], h=P["vane.thickness"],
                    m=P["vane.mass"], J=P["vane.inertia"], rho=P["vane.tip_radius"])

    def _housing(self):
        K = self.st.harmonics
        hc = derive_housing(K)
        f = lambdify_casadi([hc.alpha] + hc.symbols, [*hc.point, *hc.normal, hc.radius, hc.curvature_sign])
        names = parameter_names(K)
        al = ca.SX.sym("alpha")
        hp = ca.SX.sym("hp", len(names))
        out = f(al, *[hp[i] for i in range(hp.shape[0])])
        self.housing_raw = ca.Function("housing_raw", [al, hp], [ca.vertcat(*out)])
        self.hp_of_p = ca.vertcat(*[self.P[n] for n in names])

    def housing(self, alpha):
        o = self.housing_raw(alpha, self.hp_of_p)
        return dict(C=o[0:2], n=o[2:4], r=o[4], curvature=o[5])

    def friction(self, v, which):
        return laws.friction_coefficient(v, *friction_args(self.P, which), CASADI_OPS)

    # -- constrained model (Model 2) ------------------------------------------------------------
    @staticmethod
    def to_rotor(theta, vec):
        """Inertial components -> rotor-frame components (turn by -theta)."""
        c, s_ = ca.cos(theta), ca.sin(theta)
        return ca.vertcat(c * vec[0] + s_ * vec[1], -s_ * vec[0] + c * vec[1])

    def tip_centre_target(self, theta, alpha):
        """Where the tip-arc centre P must be for contact at housing point alpha (rotor frame)."""
        hs = self.housing(alpha)
        return self.to_rotor(theta, hs["C"] + self.geometry()["rho"] * hs["n"])

    def constraint_expr(self, theta, phi, s, alpha):
        g = self.geometry()
        m = self.mech(phi=phi, s=s, **g)
        return m["P"] - self.tip_centre_target(theta, alpha)

    def ray_guess(self, theta, Ob, u):
        """Housing parameter alpha where the slot centre line (Ob + lambda u, rotor frame) meets
        the base ellipse: a closed form, exact when there are no harmonics."""
        c, s_ = ca.cos(theta), ca.sin(theta)
        Ob_i = ca.vertcat(c * Ob[0] - s_ * Ob[1], s_ * Ob[0] + c * Ob[1])
        u_i = ca.vertcat(c * u[0] - s_ * u[1], s_ * u[0] + c * u[1])
        # initial guess: the ray Ob + lambda u meets the base ellipse (closed form, exact when
        # rho = 0 and there are no harmonics)
        ch = ca.vertcat(self.P["housing.center.0"], self.P["housing.center.1"])
        psi = self.P["housing.angle"]
        cp, sp_ = ca.cos(psi), ca.sin(psi)
        d = Ob_i - ch
        dx, dy = cp * d[0] + sp_ * d[1], -sp_ * d[0] + cp * d[1]
        ux, uy = cp * u_i[0] + sp_ * u_i[1], -sp_ * u_i[0] + cp * u_i[1]
        lam = base_ray(dx, dy, ux, uy, self.P["housing.a"], self.P["housing.b"], ca)
        X = Ob_i + lam * u_i
        return ca.atan2(X[1] - ch[1], X[0] - ch[0])

    def newton_alpha(self, alpha, gap, args, syms, a_sym):
        """Newton iterations on gap(alpha) = 0; returns (alpha, |gap|)."""
        step = ca.Function("newton_step", [*syms, a_sym, self.p],
                           [a_sym - gap / ca.jacobian(gap, a_sym), ca.fabs(gap)], {"cse": True})
        for _ in range(NEWTON_ITERATIONS["harmonics" if self.st.harmonics else "plain"]):
            alpha, _ = step(*args, alpha, self.p)
        _, res = step(*args, alpha, self.p)
        return alpha, res

    def solve_position(self, theta, phi):
        """P = C(alpha) + rho n(alpha) lies on the slot centre line: a scalar equation in alpha,
        g(alpha) = (target(alpha) - Ob) . w = 0, solved by Newton from a ray/housing guess;
        then s follows along u."""
        g = self.geometry()
        base = self.mech(phi=phi, **g)
        Ob, u, w = base["Ob"], base["u"], base["w"]
        alpha = self.ray_guess(theta, Ob, u)
        a_s, th_s, ph_s = ca.SX.sym("a"), ca.SX.sym("th"), ca.SX.sym("ph")
        bs = self.mech(phi=ph_s, **g)
        gap = ca.dot(self.tip_centre_target(th_s, a_s) - bs["Ob"], bs["w"])
        alpha, res = self.newton_alpha(alpha, gap, [theta, phi], [th_s, ph_s], a_s)
        s = ca.dot(self.tip_centre_target(theta, alpha) - Ob, u) - g["L"] + g["rho"]
        return s, alpha, res

    def kinematics_constrained(self, theta, omega, omegadot, phi):
        s, alpha, res = self.solve_position(theta, phi)
        return self.kinematics_at(theta, omega, omegadot, phi, s, alpha, res)

    def kinematics_at(self, theta, omega, omegadot, phi, s, alpha, res=0.0):
        """Velocities and accelerations at a solved position (s, alpha)."""
        # velocity and acceleration from the constraint (exact derivatives of Phi)
        th, ys, ya = ca.SX.sym("th"), ca.SX.sym("s"), ca.SX.sym("a")
        q = ca.vertcat(th, ys, ya)
        qd = ca.SX.sym("qd", 3)
        ph = ca.SX.sym("ph")
        phi_e = self.constraint_expr(th, ph, ys, ya)
        Phi_q = ca.jacobian(phi_e, q)
        gamma = ca.jacobian(ca.mtimes(Phi_q, qd), q) @ qd  # (Phi_q qdot)_q qdot
        kin = ca.Function("constraint_terms", [q, qd, ph, self.p], [Phi_q, gamma])
        Pq, _ = kin(ca.vertcat(theta, s, alpha), ca.DM.zeros(3), phi, self.p)
        Jy, Jt = Pq[:, 1:3], Pq[:, 0]
        yd = -ca.solve(Jy, Jt * omega)
        qdot = ca.vertcat(omega, yd)
        _, gam = kin(ca.vertcat(theta, s, alpha), qdot, phi, self.p)
        ydd = -ca.solve(Jy, Jt * omegadot + gam)
        return dict(s=s, alpha=alpha, sdot=yd[0], alphadot=yd[1], sddot=ydd[0], res=res)

    def vane_constrained(self) -> ca.Function:
        theta, omega, omegadot, phi, factor = (ca.SX.sym(n) for n in
                                              ("theta", "omega", "omegadot", "phi", "factor"))
        k = self.kinematics_constrained(theta, omega, omegadot, phi)
        hs = self.housing(k["alpha"])
        C, n = self.to_rotor(theta, hs["C"]), self.to_rotor(theta, hs["n"])
        g = self.geometry()
        common = dict(theta=theta, omega=omega, omegadot=omegadot, phi=phi, s=k["s"],
                      sdot=k["sdot"], sddot=k["sddot"], Cx=C[0], Cy=C[1], nx=n[0], ny=n[1],
                      c_visc=self.P["effects.viscous_tip_friction"], **g)
        v_t = self.mech(**common)["tip_slip"]
        mu_h = factor * self.friction(v_t, "housing")
        mu_r = factor * self.friction(k["sdot"], "slot")  # a vane's material/finish: tip and slot
        common.update(mu_h=mu_h, mu_r=mu_r)
        best, n_cons, amb, final = self.solve_contact_sides(("N", "F1", "F2"), common)
        outs = dict(s=k["s"], sdot=k["sdot"], sddot=k["sddot"], alpha=k["alpha"],
                    alphadot=k["alphadot"], normal=best[0], slot1=best[1], slot2=best[2],
                    torque_share=final["torque_share"], tip_slip=v_t, mu_housing=mu_h,
                    mu_slot=mu_r, kinetic_energy=final["kinetic_energy"], n_consistent=n_cons,
                    ambiguity=amb, position_residual=k["res"],
                    # d(torque share)/d(omegadot) on the selected branch, for forward dynamics
                    torque_slope=ca.jacobian(final["torque_share"], omegadot))
        return ca.Function("vane_constrained", [theta, omega, omegadot, phi, factor, self.p],
                           [outs[nm] for nm in VANE_OUTPUTS],
                           ["theta", "omega", "omegadot", "phi", "factor", "p"], list(VANE_OUTPUTS),
                           {"cse": True})

    def solve_contact_sides(self, unknowns, common, extra=None):
        """Solve the three vane equations (slide, lateral, tilt) for `unknowns` -- (N, F1, F2) in
        Model 2, (sddot, F1, F2) in Model 1 -- for every contact-side set (sigma1, sigma2); keep the
        consistent one (sign F_j = sigma_j). Returns (solution, number of consistent sets,
        ambiguity between consistent sets relative to the force scale, mechanics at the solution)."""
        x = ca.SX.sym("x", 3)
        sig = ca.SX.sym("sig", 2)
        m = self.mech(sigma1=sig[0], sigma2=sig[1], **dict(zip(unknowns, [x[0], x[1], x[2]])), **common)
        eqs = ca.vertcat(m["eq_slide"], m["eq_lateral"], m["eq_tilt"])
        if extra is not None:  # generalised forces of further loads (gas pressure, spec §8)
            eqs = eqs + ca.vertcat(*extra)
        A = ca.jacobian(eqs, x)  # the equations are linear in x for a fixed sign set
        b = -ca.substitute(eqs, x, ca.DM.zeros(3))
        cands, errs, scales = [], [], []
        for sg in SIGN_SETS:
            xi = _solve3(ca.substitute(A, sig, ca.DM(sg)), ca.substitute(b, sig, ca.DM(sg)))
            cands.append(xi)
            errs.append(ca.fmax(0, -sg[0] * xi[1]) + ca.fmax(0, -sg[1] * xi[2]))
            scales.append(ca.fabs(xi[1]) + ca.fabs(xi[2]) + (ca.fabs(xi[0]) if unknowns[0] == "N" else 0))
        scale = scales[0]
        for sc in scales[1:]:
            scale = ca.fmax(scale, sc)
        tol = CONSISTENCY_TOL * scale + 1e-300
        best, best_err = cands[0], errs[0]
        for xi, ei in zip(cands[1:], errs[1:]):
            take = ei < best_err
            best = ca.if_else(take, xi, best)
            best_err = ca.if_else(take, ei, best_err)
        n_cons = sum(ca.if_else(e <= tol, 1.0, 0.0) for e in errs)
        amb = 0.0
        for xi, ei in zip(cands, errs):
            diff = ca.mmax(ca.fabs(xi[1:] - best[1:])) / (scale + 1e-300)
            amb = ca.fmax(amb, ca.if_else(ei <= tol, diff, 0.0))
        sel = dict(zip(unknowns, [best[0], best[1], best[2]]))
        final = self.mech(sigma1=ca.if_else(best[1] >= 0, 1.0, -1.0),
                          sigma2=ca.if_else(best[2] >= 0, 1.0, -1.0), **sel, **common)
        return best, n_cons, amb, final

    # -- N-vane assembly (MX: the vane function is generated once and called N times) ----------
    def slot_angles(self, p):
        N = self.st.vanes
        idx = {q.name: i for i, q in enumerate(self.params)}
        phi0 = p[idx["rotor.first_slot_angle"]]
        return ca.horzcat(*[phi0 + 2 * math.pi * i / N for i in range(N)])

    def factors(self, p):
        idx = {q.name: i for i, q in enumerate(self.params)}
        return ca.horzcat(*[p[idx[f"effects.vane_friction_factor.{i}"]] for i in range(self.st.vanes)])

    def pget(self, p, name):
        return p[[q.name for q in self.params].index(name)]

    def housing_function(self):
        al = ca.SX.sym("alpha")
        h = self.housing(al)
        return ca.Function("housing_curve", [al, self.p], [h["C"], h["n"], h["r"], h["curvature"]],
                           ["alpha", "p"], ["point", "normal_vector", "radius", "curvature"])
