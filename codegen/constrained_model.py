"""The constrained model (Model 2) variant: the vane function mapped over the vanes and
assembled into the inverse and forward dynamics, the torque-drive ODE, the positions, and the
report form of the equations (see `codegen.builder` for the per-vane model)."""
from __future__ import annotations

import math

import casadi as ca

from pumpsim.model_spec.outputs import VANE_OUTPUTS
from pumpsim.model_spec.parameters import Structure

from .builder import Builder, BuiltModel, newton_omegadot, rotor_torque


class ConstrainedBuilder(Builder):
    """Builder of Model 2: every vane's tip on the housing, the rotor angle the one coordinate."""

    def assemble(self, vane_fn):
        N = self.st.vanes
        vmap = vane_fn.map(N)
        p = ca.MX.sym("p", len(self.params))
        theta, omega, omegadot, tau = (ca.MX.sym(n) for n in ("theta", "omega", "omegadot", "torque"))
        phis, facs = self.slot_angles(p), self.factors(p)
        Ir, tb = self.pget(p, "rotor.inertia"), self.pget(p, "operation.bearing_torque")

        def required_torque(wd):
            outs = vmap(theta, omega, wd, phis, facs, p)
            return rotor_torque(Ir, tb, wd, outs[VANE_OUTPUTS.index("torque_share")]), outs

        tq, outs = required_torque(omegadot)
        inv = ca.Function("inverse_dynamics", [theta, omega, omegadot, p], [tq, *outs],
                          ["theta", "omega", "omegadot", "p"], ["torque", *VANE_OUTPUTS])
        slope_i = VANE_OUTPUTS.index("torque_slope")

        def required(wd):
            rt, o = required_torque(wd)
            return rt, o[slope_i]

        w = newton_omegadot(required, Ir, tau)
        rt, outs_f = required_torque(w)
        r_fin = rt - tau
        fwd = ca.Function("forward_dynamics", [theta, omega, tau, p], [w, r_fin, *outs_f],
                          ["theta", "omega", "torque", "p"], ["omegadot", "torque_residual", *VANE_OUTPUTS])
        x = ca.MX.sym("x", 2)
        wd_x = fwd(x[0], x[1], tau, p)[0]
        ode = ca.Function("ode_rhs", [x, tau, p], [ca.vertcat(x[1], wd_x)],
                          ["x", "torque", "p"], ["xdot"])
        # positions only (geometry checks)
        ppos = ca.Function("positions", [theta, p],
                           [vmap(theta, 0, 0, phis, facs, p)[i] for i in
                            (VANE_OUTPUTS.index("s"), VANE_OUTPUTS.index("alpha"),
                             VANE_OUTPUTS.index("position_residual"))],
                           ["theta", "p"], ["s", "alpha", "position_residual"])
        return inv, fwd, ode, ppos

    # -- report form (§6.3): Phi(q), Phi_q, gamma and [M V; Phi_q 0][qdd; eps] = [delta; gamma] --
    def report_form(self):
        N = self.st.vanes
        p = self.p
        q = ca.SX.sym("q", 1 + 2 * N)  # theta, s_0..s_{N-1}, alpha_0..alpha_{N-1}
        qd = ca.SX.sym("qd", 1 + 2 * N)
        sig = ca.SX.sym("sigma", 2 * N)
        drive = ca.SX.sym("omegadot")  # speed drive: theta'' = omegadot
        qdd = ca.SX.sym("qdd", 1 + 2 * N)
        eps = ca.SX.sym("eps", 3 * N)  # N_i, F1_i, F2_i
        tau = ca.SX.sym("tau")
        th = q[0]
        phis = [self.pget(p, "rotor.first_slot_angle") + 2 * math.pi * i / N for i in range(N)]
        g = self.geometry()
        Phi, eqs = [], []
        rotor = tau - self.P["operation.bearing_torque"] - self.P["rotor.inertia"] * qdd[0]
        for i in range(N):
            s, al = q[1 + i], q[1 + N + i]
            Phi.append(self.constraint_expr(th, phis[i], s, al))
            hs = self.housing(al)
            C, n = self.to_rotor(th, hs["C"]), self.to_rotor(th, hs["n"])
            kw = dict(theta=th, omega=qd[0], omegadot=qdd[0], phi=phis[i], s=s, sdot=qd[1 + i],
                      sddot=qdd[1 + i], Cx=C[0], Cy=C[1], nx=n[0], ny=n[1],
                      c_visc=self.P["effects.viscous_tip_friction"], **g)
            v_t = self.mech(**kw)["tip_slip"]
            mu_h = self.P[f"effects.vane_friction_factor.{i}"] * self.friction(v_t, "housing")
            mu_r = self.P[f"effects.vane_friction_factor.{i}"] * self.friction(qd[1 + i], "slot")
            m = self.mech(N=eps[3 * i], F1=eps[3 * i + 1], F2=eps[3 * i + 2], sigma1=sig[2 * i],
                          sigma2=sig[2 * i + 1], mu_h=mu_h, mu_r=mu_r, **kw)
            eqs += [m["eq_slide"], m["eq_lateral"], m["eq_tilt"]]
            rotor -= m["torque_share"]
        Phi = ca.vertcat(*Phi)
        Phi_q = ca.jacobian(Phi, q)
        gamma = -ca.jacobian(Phi_q @ qd, q) @ qd
        dyn = ca.vertcat(rotor, *eqs)
        unknowns = ca.vertcat(qdd, eps, tau)
        rows = ca.vertcat(dyn, Phi_q @ qdd - gamma, qdd[0] - drive)
        K = ca.jacobian(rows, unknowns)
        rhs = -ca.substitute(rows, unknowns, ca.DM.zeros(unknowns.shape[0]))
        f_phi = ca.Function("constraint", [q, p], [Phi], ["q", "p"], ["phi"])
        f_phiq = ca.Function("constraint_jacobian", [q, p], [Phi_q], ["q", "p"], ["phi_q"])
        f_gam = ca.Function("acceleration_rhs", [q, qd, p], [gamma], ["q", "qd", "p"], ["gamma"])
        f_dyn = ca.Function("dynamic_system", [q, qd, sig, drive, p], [K, rhs],
                            ["q", "qd", "sigma", "omegadot", "p"], ["matrix", "rhs"])
        return f_phi, f_phiq, f_gam, f_dyn


def build_constrained_model(structure: Structure) -> BuiltModel:
    """Every exported CasADi function of a constrained variant (no compilation here)."""
    b = ConstrainedBuilder(structure)
    vane = b.vane_constrained()
    inv, fwd, ode, pos = b.assemble(vane)
    f_phi, f_phiq, f_gam, f_dyn = b.report_form()
    fns = {f.name(): f for f in (inv, fwd, ode, pos, f_phi, f_phiq, f_gam, f_dyn,
                                 b.housing_function())}
    return BuiltModel(structure, b.params, fns)
