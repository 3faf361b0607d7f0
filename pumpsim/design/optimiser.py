"""Design optimisation: minimise an output subject to output constraints, the varied keys within
their bounds.

One objective: SciPy SLSQP (default) or trust-constr, with gradients from the compiled kernel's
forward-mode AD in p (and in the speed). A config key reaches p through the config (housing.radius
sets both semi-axes; vane.mass also moves the derived default vane.inertia = m (L² + h²)/12): that
map is polynomial of degree <= 2 in each key, so its central difference is exact up to rounding,
and the chain dp/dx -> kernel AD -> reduction gives the exact gradient of a smooth output (a max or
min output: the gradient at its arg-max, a subgradient). Variables are scaled to [0, 1] by their
bounds. With several speeds, the objective is the mean over the speeds and every constraint holds
at every speed.

Several objectives: a Pareto front by pymoo's NSGA-II (population, generations in [optimize]).
"""
from __future__ import annotations

import time

import numpy as np

from ..config import config_from_dict
from ..errors import ConfigError, SolverError
from ..geometry import mouth_depth
from ..kernels import load_kernels
from .evaluate import (design_speeds, evaluate_rows, kernel_tangents, prepare, revolution)
from .outputs import reduce_revolution
from .pneumatic import GAS_OUTPUTS
from .study import SPEED_KEY, apply_values

METHODS = ("slsqp", "trust-constr", "nsga2")
REL_STEP = 1e-6  # central difference of the (polynomial) config -> p map


class DesignFunction:
    """Outputs and their exact gradients for designs x (values of the varied keys)."""

    def __init__(self, study):
        self.study = study
        self.keys = study.keys
        self.evaluations = 0

    def values(self, x) -> dict:
        return dict(zip(self.keys, map(float, x)))

    def _p(self, x):
        pr = prepare(self.study, self.values(x))
        if pr.status != "ok":
            raise SolverError(f"the optimiser reached a design the config rejects ({pr.status}) at "
                              + ", ".join(f"{k} = {v:.6g}" for k, v in self.values(x).items()))
        return pr

    def evaluate(self, x, gradient=True):
        """(outputs per speed [dict], gradients per speed [dict name -> (keys,)])."""
        self.evaluations += 1
        x = np.asarray(x, dtype=float)
        pr = self._p(x)
        cfg, p = pr.cfg, pr.p
        kern = load_kernels(cfg.structure_for("constrained"))
        names = cfg.parameters("constrained").names
        iv = {n: i for i, n in enumerate(names)}
        nk = len(self.keys)
        dP, domega = np.zeros((nk, p.size)), np.zeros(nk)
        dlm, darea = np.zeros(nk), np.zeros(nk)
        if gradient:
            for j, key in enumerate(self.keys):
                if key == SPEED_KEY:
                    domega[j] = 1.0
                    continue
                h = REL_STEP * max(abs(x[j]), 1e-3 * _span(self.study.variables[j]))
                xp, xm = x.copy(), x.copy()
                xp[j] += h
                xm[j] -= h
                pp, pm = self._p(xp), self._p(xm)
                dP[j] = (pp.p - pm.p) / (2 * h)
                dlm[j] = (mouth_depth(pp.values) - mouth_depth(pm.values)) / (2 * h)
                darea[j] = (pp.constants()["tip_area"] - pm.constants()["tip_area"]) / (2 * h)
        theta = revolution(cfg.angle, self.study.revolution_samples)
        from .evaluate import evaluate_designs

        outs, grads = [], []
        const = pr.constants()
        for w in design_speeds(self.study, cfg):
            ev = evaluate_designs(kern, p[None, :], theta, np.array([w]))
            a = {k: arr[0] for k, arr in ev.items()}
            if gradient:
                da = kernel_tangents(kern, p, theta, w, dP, domega)
                dpar = {"c_visc": dP[:, iv["effects.viscous_tip_friction"]], "L": dP[:, iv["vane.length"]],
                        "lm": dlm, "tip_area": darea}
                o, g = reduce_revolution(a, const, da, dpar)
            else:
                o, g = reduce_revolution(a, const)
            outs.append(o)
            grads.append(g)
        return outs, grads


def _span(var):
    return (var.bounds[1] - var.bounds[0]) if var.bounds else 1.0


def _check(study):
    if not study.objective:
        raise ConfigError("optimize needs [objective] minimize = OUTPUT")
    if study.function is not None:
        raise ConfigError("optimize runs on a pump config (study.config)")
    gas = [o for o in list(study.objective) + list(study.constraints) if o in GAS_OUTPUTS]
    if gas:
        raise ConfigError(f"optimize: {gas[0]} comes from the gas model's periodic steady state, which "
                          "has no kernel gradient here; sweep it (pumpsim sweep) instead")
    if study.booster_pressure is not None:
        raise ConfigError("optimize: the config has the gas tables, so its outputs carry the gas loads of "
                          "the gas model's periodic steady state, which has no kernel gradient here; sweep "
                          "the design (pumpsim sweep), or optimise the mechanics alone on the config "
                          "without its gas tables")
    for v in study.variables:
        if v.bounds is None:
            raise ConfigError(f"vary.\"{v.key}\" needs bounds = [low, high] (or a range or distribution "
                              "that implies them) for optimisation")
        if v.key == "rotor.vanes":
            raise ConfigError("rotor.vanes is an integer (structural) key: sweep it with a grid instead")
        _bounds_admissible(study, v)


def _bounds_admissible(study, v) -> None:
    """Each end of a variable's bounds a config the model takes (the others at their base values):
    an optimiser must not be sent where no design exists."""
    if v.key == SPEED_KEY:
        return
    for end in v.bounds:
        try:
            config_from_dict(apply_values(study.base, {v.key: end}))
        except ConfigError as e:
            raise ConfigError(f"vary.\"{v.key}\".bounds end {end:g} is no admissible design ({e}); "
                              "narrow the bounds") from None


def optimize(study, method=None, max_iter=None, tol=None, progress=None) -> dict:
    _check(study)
    opt = dict(study.optimize or {})
    bad = set(opt) - {"method", "iterations", "tolerance", "population", "generations", "seed"}
    if bad:
        raise ConfigError(f"unknown key 'optimize.{sorted(bad)[0]}'")
    method = method or opt.get("method") or ("nsga2" if len(study.objective) > 1 else "slsqp")
    if method not in METHODS:
        raise ConfigError(f"optimize.method must be one of {', '.join(METHODS)}, got {method!r}")
    if len(study.objective) > 1 and method != "nsga2":
        raise ConfigError("several objectives need optimize.method = \"nsga2\" (a Pareto front)")
    if method == "nsga2":
        return pareto(study, opt)
    return _gradient_based(study, method, max_iter or int(opt.get("iterations", 100)),
                           tol or float(opt.get("tolerance", 1e-9)), progress)


def _start_point(study, lo, hi):
    """Each variable's start, else its config value, else its bounds' midpoint; clipped to the bounds."""
    x0 = np.array([v.start if v.start is not None else (v.base if v.base is not None else 0.5 * (a + b))
                   for v, a, b in zip(study.variables, lo, hi)])
    return np.clip(x0, lo, hi)


def _constraint_terms(study, outs0) -> list:
    """One (output, speed index, side, bound, scale) per given bound per speed; scale from the start."""
    cons = []
    for name, (clo, chi) in study.constraints.items():
        for k in range(len(outs0)):
            for side, b in (("lower", clo), ("upper", chi)):
                if b is not None:
                    cons.append((name, k, side, b, max(abs(b), abs(outs0[k][name]), 1e-300)))
    return cons


def _constraint_report(study, outs, speeds) -> dict:
    """Each constraint's value at each speed and whether it holds (relative slack 1e-6)."""
    conres = {}
    for name, (clo, chi) in study.constraints.items():
        for k, w in enumerate(speeds):
            val = outs[k][name]
            ok = (clo is None or val >= clo - 1e-6 * max(1, abs(clo))) and (chi is None or val <= chi + 1e-6 * max(1, abs(chi)))
            conres[name if len(speeds) == 1 else f"{name}@{w:g}"] = {
                "value": float(val), "lower": clo, "upper": chi, "satisfied": bool(ok)}
    return conres


class _Scaled:
    """The optimisation in the unit cube of the varied keys: objective and constraints scaled by
    their start values, each design evaluated once for its value and gradient (the last one kept),
    and the iterations recorded."""

    def __init__(self, study, progress):
        self.fn = DesignFunction(study)
        self.lo = np.array([v.bounds[0] for v in study.variables])
        self.hi = np.array([v.bounds[1] for v in study.variables])
        self.span = self.hi - self.lo
        self.x0 = _start_point(study, self.lo, self.hi)
        self.name = study.objective[0]
        self.cache, self.history, self.progress = {}, [], progress
        self.outs0, _ = self.fn.evaluate(self.x0, gradient=False)
        self.f_scale = max(abs(self.mean(self.outs0)), 1e-300)
        self.cons = _constraint_terms(study, self.outs0)

    def mean(self, outs) -> float:
        return float(np.mean([x[self.name] for x in outs]))

    def ev(self, z):
        key = tuple(np.round(z, 15))
        if key not in self.cache:
            self.cache.clear()
            self.cache[key] = self.fn.evaluate(self.lo + z * self.span)
        return self.cache[key]

    def f(self, z):
        return self.mean(self.ev(z)[0]) / self.f_scale

    def df(self, z):
        return np.mean([x[self.name] for x in self.ev(z)[1]], axis=0) * self.span / self.f_scale

    def c(self, z):
        o = self.ev(z)[0]
        return np.array([(o[k][n] - b if s == "lower" else b - o[k][n]) / sc for n, k, s, b, sc in self.cons])

    def dc(self, z):
        g = self.ev(z)[1]
        return np.array([(g[k][n] if s == "lower" else -g[k][n]) * self.span / sc
                         for n, k, s, b, sc in self.cons])

    def record(self, z, *_):
        viol = float(max([0.0, *(-self.c(z))])) if self.cons else 0.0
        self.history.append({"design": self.fn.values(self.lo + z * self.span),
                             "objective": self.mean(self.ev(z)[0]), "violation": viol})
        if self.progress:
            self.progress(len(self.history), self.history[-1])


def _gradient_based(study, method, max_iter, tol, progress):
    from scipy.optimize import Bounds, NonlinearConstraint, minimize

    pb = _Scaled(study, progress)
    z0 = (pb.x0 - pb.lo) / pb.span
    pb.record(z0)
    t0 = time.perf_counter()
    if method == "slsqp":
        res = minimize(pb.f, z0, jac=pb.df, method="SLSQP", bounds=[(0.0, 1.0)] * len(z0),
                       constraints=[{"type": "ineq", "fun": pb.c, "jac": pb.dc}] if pb.cons else [],
                       options={"maxiter": max_iter, "ftol": tol}, callback=pb.record)
    else:
        nl = [NonlinearConstraint(pb.c, 0.0, np.inf, jac=pb.dc)] if pb.cons else []
        res = minimize(pb.f, z0, jac=pb.df, method="trust-constr", bounds=Bounds(0.0, 1.0), constraints=nl,
                       options={"maxiter": max_iter, "gtol": tol, "xtol": tol},
                       callback=lambda z, *a: pb.record(z))
    return _optimum(study, pb, method, res, t0)


def _optimum(study, pb, method, res, t0) -> dict:
    """The optimiser's result as the JSON of `pumpsim optimize`."""
    fn = pb.fn
    x = pb.lo + np.clip(res.x, 0, 1) * pb.span
    outs, grads = fn.evaluate(x)
    speeds = design_speeds(study, prepare(study, fn.values(x)).cfg)
    conres = _constraint_report(study, outs, speeds)
    feasible = all(v["satisfied"] for v in conres.values())
    return {
        "method": method, "success": bool(res.success) and feasible, "message": str(res.message),
        "objective": {"minimize": pb.name, "value": pb.mean(outs), "start": pb.mean(pb.outs0)},
        "design": fn.values(x), "start": fn.values(pb.x0),
        "bounds": {k: [float(a), float(b)] for k, a, b in zip(study.keys, pb.lo, pb.hi)},
        "constraints": conres, "feasible": feasible,
        "outputs": [{k: (bool(v) if isinstance(v, (bool, np.bool_)) else float(v)) for k, v in o.items()}
                    for o in outs],
        "gradient": {k: float(gv) for k, gv in zip(study.keys, np.mean([g[pb.name] for g in grads], axis=0))},
        "speeds": [float(w) for w in speeds], "iterations": pb.history, "evaluations": fn.evaluations,
        "seconds": time.perf_counter() - t0,
    }


def pareto(study, opt) -> dict:
    """NSGA-II Pareto front of several objectives (pymoo), constraints as g(x) <= 0."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize as pymoo_minimize

    lo = np.array([v.bounds[0] for v in study.variables])
    hi = np.array([v.bounds[1] for v in study.variables])
    objs = study.objective
    cons = [(n, s, b) for n, (a, z) in study.constraints.items() for s, b in (("lower", a), ("upper", z))
            if b is not None]
    n_vanes = max(int(study.base["rotor"]["vanes"]), 1)
    counter = {"designs": 0, "generation": 0}
    history = []

    class _P(Problem):
        def __init__(self):
            super().__init__(n_var=len(lo), n_obj=len(objs), n_ieq_constr=len(cons), xl=lo, xu=hi)

        def _evaluate(self, X, out, *args, **kw):
            ids = np.arange(counter["designs"], counter["designs"] + len(X))
            counter["designs"] += len(X)
            rows = evaluate_rows(study, X, ids, n_vanes)
            F = np.full((len(X), len(objs)), np.inf)
            G = np.full((len(X), len(cons)), np.inf)
            by = {}
            for r in rows:
                by.setdefault(r["design"] - ids[0], []).append(r)
            for i, rs in by.items():
                if any(r["status"] != "ok" for r in rs):
                    continue
                F[i] = [np.mean([r[o] for r in rs]) for o in objs]
                G[i] = [max((b - r[n]) if s == "lower" else (r[n] - b) for r in rs) for n, s, b in cons]
            out["F"] = F
            if cons:
                out["G"] = G
            counter["generation"] += 1
            fin = np.isfinite(F).all(axis=1)
            history.append({"generation": counter["generation"], "designs": int(len(X)),
                            "evaluated": int(fin.sum()),
                            "best": [float(F[fin, j].min()) if fin.any() else None for j in range(len(objs))]})

    pop = int(opt.get("population", 40))
    gens = int(opt.get("generations", 30))
    seed = int(opt.get("seed", study.seed))
    t0 = time.perf_counter()
    res = pymoo_minimize(_P(), NSGA2(pop_size=pop), ("n_gen", gens), seed=seed, verbose=False)
    front = []
    if res.X is not None:
        Xf = np.atleast_2d(res.X)
        Ff = np.atleast_2d(res.F)
        order = np.argsort(Ff[:, 0])
        for i in order:
            front.append({"design": dict(zip(study.keys, map(float, Xf[i]))),
                          "objectives": dict(zip(objs, map(float, Ff[i])))})
    return {"method": "nsga2", "success": bool(front), "objectives": objs, "front": front,
            "population": pop, "generations": gens, "seed": seed, "evaluations": counter["designs"],
            "iterations": history, "seconds": time.perf_counter() - t0,
            "message": "Pareto front" if front else "no feasible design found"}


def gradient_check(study, x, rel_step=1e-6) -> dict:
    """Kernel-AD gradients of every numeric output vs central differences of the whole pipeline."""
    fn = DesignFunction(study)
    x = np.asarray(x, dtype=float)
    outs, grads = fn.evaluate(x)
    fd = {}
    for j, var in enumerate(study.variables):
        h = rel_step * max(abs(x[j]), 1e-3 * _span(var))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        op, _ = fn.evaluate(xp, gradient=False)
        om, _ = fn.evaluate(xm, gradient=False)
        for name in grads[0]:
            fd.setdefault(name, np.zeros(len(x)))[j] = (op[0][name] - om[0][name]) / (2 * h)
    return {"ad": {k: np.asarray(v) for k, v in grads[0].items()}, "fd": fd, "values": outs[0]}


__all__ = ["optimize", "pareto", "gradient_check", "DesignFunction"]
