"""The constrained model's inverse dynamics in NumPy, vectorised over samples, lambdified from the
same SymPy expressions as the compiled kernel: what a Python user without a code generator would
write. Used as the benchmark baseline and as an independent cross-check of the CasADi assembly.
"""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from pumpsim.model_spec import laws
from pumpsim.model_spec.parameters import Structure, friction_args, layout

from .housing import derive_housing, parameter_names
from .mechanics import SYMBOL_NAMES, derive_vane
from .builder import SIGN_SETS

NEWTON_ITERATIONS = 6  # 2x2 Newton in (s, alpha) from a ray/circle fixed-point guess
RAY_ITERATIONS = 4


class _NumpyModel:
    """Shared set-up: the parameter names, the one-vane mechanics and the housing curve."""

    def __init__(self, structure: Structure):
        self.st = structure
        self.names = [q.name for q in layout(structure)]
        self.mech = derive_vane()
        self.hc = derive_housing(structure.harmonics)
        self.hsyms = self.hc.symbols


class NumpyConstrainedModel(_NumpyModel):
    def __init__(self, structure: Structure):
        super().__init__(structure)
        mech, hc = self.mech, self.hc
        S = mech.sym
        al = hc.alpha
        C, n = sp.Matrix(hc.point), sp.Matrix(hc.normal)
        P = sp.Matrix(mech.points["P"])  # rotor frame
        th = S["theta"]
        to_rotor = sp.Matrix([[sp.cos(th), sp.sin(th)], [-sp.sin(th), sp.cos(th)]])
        Phi = P - to_rotor * (C + S["rho"] * n)
        q = [S["theta"], S["s"], al]
        Phi_q = Phi.jacobian(q)
        qd = sp.symbols("qd0:3", real=True)
        gamma = (Phi_q * sp.Matrix(qd)).jacobian(q) * sp.Matrix(qd)
        geo = [S[k] for k in ("theta", "phi", "s", "slot_radius", "slot_tilt", "rotor_radius", "L", "h",
                              "m", "J", "rho")]
        self._phi = _lambdify_matrices(geo + [al] + self.hsyms, [Phi, Phi_q])
        self._gamma = _lambdify_matrices(geo + [al] + self.hsyms + list(qd), [gamma])
        self._housing = sp.lambdify([al] + self.hsyms, [hc.radius, *hc.point, *hc.normal], "numpy", cse=True)
        Cr, nr = to_rotor * C, to_rotor * n
        self._housing_rotor = sp.lambdify([th, al] + self.hsyms, [*Cr, *nr], "numpy", cse=True)
        ob_i = to_rotor.T * sp.Matrix(mech.points["Ob"])
        u_i = to_rotor.T * sp.Matrix(mech.slot_u)
        self._ray = sp.lambdify(geo, [*ob_i, *u_i], "numpy", cse=True)
        x = [S["N"], S["F1"], S["F2"]]
        eqs = sp.Matrix([mech.equations[k] for k in ("slide", "lateral", "tilt")])
        A = eqs.jacobian(x)
        b = -eqs.subs({xi: 0 for xi in x})
        args = [S[nm] for nm in SYMBOL_NAMES if nm not in ("N", "F1", "F2")]
        self._dyn_args = [nm for nm in SYMBOL_NAMES if nm not in ("N", "F1", "F2")]
        self._lin = _lambdify_matrices(args, [A, b])
        self._slip = sp.lambdify(args, mech.tip_slip, "numpy", cse=True)
        self._share = sp.lambdify([S[nm] for nm in SYMBOL_NAMES], mech.drive_torque_share, "numpy", cse=True)

    def inverse_dynamics(self, theta, omega, omegadot, p):
        theta = np.asarray(theta, dtype=float)
        n = theta.size
        v = dict(zip(self.names, p))
        hp, g, gl, fh, fs = _unpack(v, self.st.harmonics)
        N = self.st.vanes
        torque = v["rotor.inertia"] * omegadot + v["operation.bearing_torque"] + np.zeros(n)
        normal = np.empty((N, n))
        for i in range(N):
            phi = v["rotor.first_slot_angle"] + 2 * math.pi * i / N
            obx, oby, ux, uy = self._ray(theta, phi, 0.0, *gl)
            dx, dy = obx - hp[2], oby - hp[3]
            du, dd = dx * ux + dy * uy, dx * dx + dy * dy
            r = 0.5 * (hp[0] + hp[1])
            lam = -du + np.sqrt(np.maximum(du**2 - dd + r**2, 0))
            for _ in range(RAY_ITERATIONS):
                al = np.arctan2(oby + lam * uy - hp[3], obx + lam * ux - hp[2])
                r = self._housing(al, *hp)[0]
                lam = -du + np.sqrt(np.maximum(du**2 - dd + r**2, 0))
            al = np.arctan2(oby + lam * uy - hp[3], obx + lam * ux - hp[2])
            s = lam - g["L"]
            for _ in range(NEWTON_ITERATIONS):
                Phi, Pq = self._phi(n, theta, phi, s, *gl, al, *hp)
                step = np.linalg.solve(Pq[:, :, 1:3], Phi)[:, :, 0]
                s, al = s - step[:, 0], al - step[:, 1]
            _, Pq = self._phi(n, theta, phi, s, *gl, al, *hp)
            Jy, Jt = Pq[:, :, 1:3], Pq[:, :, 0]
            yd = -np.linalg.solve(Jy, (Jt * omega)[:, :, None])[:, :, 0]
            gam = self._gamma(n, theta, phi, s, *gl, al, *hp, omega, yd[:, 0], yd[:, 1])[0][:, :, 0]
            ydd = -np.linalg.solve(Jy, (Jt * omegadot + gam)[:, :, None])[:, :, 0]
            cx, cy, nx, ny = self._housing_rotor(theta, al, *hp)
            kw = dict(theta=theta, omega=omega, omegadot=omegadot, phi=phi, s=s, sdot=yd[:, 0],
                      sddot=ydd[:, 0], Cx=cx, Cy=cy, nx=nx, ny=ny, Fb=0.0, sigma1=1.0, sigma2=1.0,
                      mu_h=0.0, mu_r=0.0, c_visc=v["effects.viscous_tip_friction"], **g)
            vt = self._slip(*[kw[a] for a in self._dyn_args])
            kw["mu_h"] = v[f"effects.vane_friction_factor.{i}"] * laws.friction_coefficient(vt, *fh)
            kw["mu_r"] = v[f"effects.vane_friction_factor.{i}"] * laws.friction_coefficient(yd[:, 0], *fs)
            best, best_err = None, None
            for s1, s2 in SIGN_SETS:
                kw["sigma1"], kw["sigma2"] = s1, s2
                A, b = self._lin(n, *[kw[a] for a in self._dyn_args])
                xs = np.linalg.solve(A, b)[:, :, 0]
                err = np.maximum(0, -s1 * xs[:, 1]) + np.maximum(0, -s2 * xs[:, 2])
                if best is None:
                    best, best_err = xs, err
                else:
                    take = err < best_err
                    best = np.where(take[:, None], xs, best)
                    best_err = np.where(take, err, best_err)
            kw.update(N=best[:, 0], F1=best[:, 1], F2=best[:, 2], sigma1=np.where(best[:, 1] >= 0, 1.0, -1.0),
                      sigma2=np.where(best[:, 2] >= 0, 1.0, -1.0))
            torque = torque + self._share(*[kw[a] for a in SYMBOL_NAMES])
            normal[i] = best[:, 0]
        return torque, normal


GEOMETRY_ORDER = ("slot_radius", "slot_tilt", "rotor_radius", "L", "h", "m", "J", "rho")


def _unpack(v, harmonics, rho=None):
    """Parameter values by name -> housing list, geometry dict and list, friction lists."""
    hp = [v[n] for n in parameter_names(harmonics)]  # a, b, centre, psi, harmonics
    g = dict(slot_radius=v["rotor.slot_radius"], slot_tilt=v["rotor.slot_tilt"],
             rotor_radius=v["rotor.radius"], L=v["vane.length"], h=v["vane.thickness"],
             m=v["vane.mass"], J=v["vane.inertia"], rho=v["vane.tip_radius"] if rho is None else rho)
    return hp, g, [g[k] for k in GEOMETRY_ORDER], friction_args(v, "housing"), friction_args(v, "slot")


def _lambdify_matrices(args, matrices):
    """Lambdify SymPy matrices entry by entry; the result maps (n, *args) to (n, rows, cols) arrays."""
    shapes = [M.shape for M in matrices]
    flat = sp.lambdify(args, [e for M in matrices for e in M], "numpy", cse=True)

    def call(n, *values):
        entries = flat(*values)
        out, k = [], 0
        for r, c in shapes:
            arr = np.empty((n, r, c))
            for i in range(r):
                for j in range(c):
                    arr[:, i, j] = entries[k]
                    k += 1
            out.append(arr)
        return out

    return call


class NumpyContactModel(_NumpyModel):
    """Model 1's right-hand side in NumPy for SciPy's solve_ivp, lambdified from the same SymPy
    mechanics: speed drive, sharp tip (rho = 0, the contact point on the slot centre line)."""

    def __init__(self, structure: Structure):
        super().__init__(structure)
        mech, hc = self.mech, self.hc
        S = mech.sym
        al = hc.alpha
        th = S["theta"]
        rot = sp.Matrix([[sp.cos(th), sp.sin(th)], [-sp.sin(th), sp.cos(th)]])
        C = rot * sp.Matrix(hc.point)
        n = rot * sp.Matrix(hc.normal)
        Ob, u, w = (sp.Matrix(mech.points["Ob"]), sp.Matrix(mech.slot_u), sp.Matrix(mech.slot_w))
        B = sp.Matrix(mech.points["B"])
        gap = (C - Ob).dot(w)  # C on the slot centre line
        delta = -(B - C).dot(n)
        q = [th, S["s"], al]
        geo = [S[k] for k in ("phi", "slot_radius", "slot_tilt", "rotor_radius", "L", "h", "m", "J", "rho")]
        args = [th, S["s"], al] + geo + self.hsyms
        self._gap = sp.lambdify(args, [gap, sp.diff(gap, al)], "numpy", cse=True)
        self._delta = sp.lambdify(args, [delta, *[sp.diff(delta, v) for v in q], *[sp.diff(gap, v) for v in q],
                                         C[0], C[1], n[0], n[1]], "numpy", cse=True)
        x = [S["sddot"], S["F1"], S["F2"]]
        eqs = sp.Matrix([mech.equations[k] for k in ("slide", "lateral", "tilt")])
        self._dyn_args = [nm for nm in SYMBOL_NAMES if nm not in ("sddot", "F1", "F2")]
        lin_args = [S[nm] for nm in self._dyn_args]
        self._lin = sp.lambdify(lin_args, [eqs.jacobian(x), -eqs.subs({xi: 0 for xi in x})], "numpy", cse=True)
        self._slip = sp.lambdify([S[nm] for nm in SYMBOL_NAMES], mech.tip_slip, "numpy", cse=True)

    def rhs_speed(self, p, theta0, omega, law_h, law_b):
        """f(t, y) for y = [s_0.., sdot_0..] at constant speed."""
        v = dict(zip(self.names, p))
        hp, g, gl, fh, fs = _unpack(v, self.st.harmonics, rho=0.0)
        ch = [v[f"contact.housing.{k}"] for k in ("stiffness", "exponent", "damping", "depth")]
        cb = [v[f"contact.bottom.{k}"] for k in ("stiffness", "exponent", "damping", "depth")]
        N = self.st.vanes
        phis = [v["rotor.first_slot_angle"] + 2 * math.pi * i / N for i in range(N)]
        alpha_prev = [None] * N

        def f(t, y):
            theta = theta0 + omega * t
            out = np.empty(2 * N)
            out[:N] = y[N:]
            for i, phi in enumerate(phis):
                s, sd = y[i], y[N + i]
                a = alpha_prev[i]
                if a is None:
                    a = theta + phi
                for _ in range(6):
                    gv, dg = self._gap(theta, s, a, phi, *gl, *hp)
                    a -= gv / dg
                alpha_prev[i] = a
                d, d_t, d_s, d_a, g_t, g_s, g_a, cx, cy, nx, ny = self._delta(theta, s, a, phi, *gl, *hp)
                ad = -(g_t * omega + g_s * sd) / g_a
                dd = d_t * omega + d_s * sd + d_a * ad
                Nf = laws.contact_force(law_h, d, dd, *ch, g["m"])
                Fb = laws.contact_force(law_b, -s, -sd, *cb, g["m"])
                kw = dict(theta=theta, omega=omega, omegadot=0.0, phi=phi, s=s, sdot=sd, Cx=cx, Cy=cy,
                          nx=nx, ny=ny, N=Nf, Fb=Fb, c_visc=0.0, sigma1=1.0, sigma2=1.0, mu_h=0.0,
                          mu_r=0.0, sddot=0.0, F1=0.0, F2=0.0, **g)
                vt = self._slip(*[kw[k] for k in SYMBOL_NAMES])
                kw["mu_h"] = v[f"effects.vane_friction_factor.{i}"] * laws.friction_coefficient(vt, *fh)
                kw["mu_r"] = v[f"effects.vane_friction_factor.{i}"] * laws.friction_coefficient(sd, *fs)
                best, best_err = None, None
                for s1, s2 in SIGN_SETS:
                    kw["sigma1"], kw["sigma2"] = s1, s2
                    A, b = self._lin(*[kw[k] for k in self._dyn_args])
                    xs = np.linalg.solve(np.asarray(A, float), np.asarray(b, float).ravel())
                    err = max(0, -s1 * xs[1]) + max(0, -s2 * xs[2])
                    if best is None or err < best_err:
                        best, best_err = xs, err
                out[N + i] = best[0]
            return out

        return f
