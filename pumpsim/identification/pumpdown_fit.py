"""Identification from a bench log (spec §10): the pump-down model (spec §8, Model 2 with gas, the
DC motor) driven by the log's measured supply voltage, compared with its booster pressure, motor
current and (when logged) speed.

The model starts where the log starts: the pump at rest (or at the speed column's first value),
the booster at the log's start pressure (BenchLog.start_pressure), the cells at the atmosphere. The
voltage between samples is the linear interpolation of the logged one.

What is compared: the booster pressure at each sample; the current and the speed as means over
consecutive blocks of about one revolution (block_samples). A bench samples the current far below
the rate at which the vanes pass, so each sample carries the vane-passing ripple at a phase that no
model reproduces over seconds (a 0.1 % speed error turns it by a revolution within ~2 s), and a
mean over less than a ripple period keeps most of it. Over a block the model's mean is exact from
the states, with no extra quadrature -- the motor equation V = R i + L di/dt + k omega gives
integral(i dt) = (integral(V dt) - k dtheta - L di) / R -- and the speed's is dtheta / dt; the log's
block means are trapezoidal means of its samples.

Each compared channel is divided by its noise sigma (robust sigma of its first differences,
floored at CHANNEL_FLOOR of the channel's size, the integrator's accuracy) so that one least-squares
cost weighs pressure, current and speed; the residual RMS is then in units of the noise (1: the
model explains the log to its noise).

The fit starts from a fast model on the pump's cycle-averaged maps (bench_fast: its fit, then
full-model steps with its Jacobian corrected by Broyden updates); the full model's Jacobian, last,
gives the covariance. The full model runs by the direct CVODES driver where it is available
(bench_sens.DirectRuns), else by CasADi's plugin (bench_model.GridRuns); the whole log in one call.
Its Jacobian (`jacobian`):
- "differences" (the default): forward differences, one run per parameter, the runs of one
  Jacobian at once in threads. The 1 % step's curvature error is a few % of a column (0.2 s log,
  rtol 1e-8: mu 6 %, motor.resistance 12 %; 0.5 s, rtol 1e-6: 2-4 %), each run's integration
  error on top at a loose tolerance (rtol 1e-4: 7-27 %).
- "sensitivities": forward sensitivities of one run (bench_sens), excluded from the error test:
  the Jacobian kernel's J s plus a difference of the right-hand side along the parameter's
  direction. A vane reversing in its slot flips its Coulomb friction within |ds/dt| < v_static
  (~1e-4 rad): a switch of the right-hand side that the sensitivities must cross as a jump (located
  by CVODES; without it the columns of mu and the resistance were 6-15 % off). With the jumps: within
  0.3 % (mu), 0.01 % (leak), 1 % (resistance), 0.2-0.3 % (tip gap, cracking, motor friction) of
  central differences at rtol 1e-8; but at rtol 1e-6 2-3.5 % and at 1e-5 12-17 % (mu, resistance),
  the band between the static and the dynamic friction the steps cross too coarsely. So it does not
  let the fit loosen its tolerance, and at rtol 1e-6 one run with sensitivities costs ~1.2 times the
  base run and the three of the differences (0.5 s log: 3.8 against 3.2 CPU s); it is the more accurate
  Jacobian at a tight tolerance (standard errors; the booster leak's column at any tolerance).
The first attempt at sensitivities kept them in the error test: 6x the steps, 33x a run's cost.
From the maps' start with differences, the fit continues in the tolerance (CONTINUATION_RTOL): the
Jacobian at the fast fit takes its difference steps at rtol 1e-5 with a 3 % step from the run at
the fit's rtol there (the runs at once on the cores), the start pressure's column from the fast
model; the Gauss-Newton steps, their residuals and the convergence test at the fit's rtol.
"""
from __future__ import annotations

import difflib
import time as _time
from dataclasses import dataclass, field

import numpy as np

from .. import interrupt
from ..benchlog import BenchLog, fit_percent, start_above_atmosphere
from ..signals import measured_noise
from ..errors import ConfigError
from ..model_spec.parameters import COF_ALIASES, GAS_ENCODED, GAS_PARAMETERS, fit_bounds, pneumatic_layout
from ..tolerances import BENCH_FIT_ATOL, BENCH_FIT_RTOL
from .current_ripple import bench_ripple
from .bench_model import START_NAME, BenchModel, block_edges, block_means, block_samples  # noqa: F401 (public here too)
from .problem import Problem, following, parameter_map, slot_ratio

CHANNEL_FLOOR = 1e-4  # a channel's noise sigma is at least this share of its largest value
DIFFERENCE_STEP = 1e-2  # forward-difference step, of the parameter's scale (see scale_of)
# tolerance continuation (identify_bench, bench_fast.fast_then_full): the Jacobian's difference steps
# at this rtol (atol in proportion; a run ~0.6 of one at 1e-6) and a wider step for its integration
# error; its noise moves the fixed point by up to 0.12 standard errors (docs: the bench-log fit)
CONTINUATION_RTOL, CONTINUATION_STEP = 1e-5, 3e-2
# a parameter's scale when its value may be 0 (no leak, no cracking pressure): a size it typically has
TYPICAL = {"booster.leak": 1e-4, "leak.tip_gap": 1e-6, "leak.end_gap": 1e-6, "valve.cracking": 100.0,
           "motor.friction": 1e-3, "mu": 0.01, "mu_slot": 0.01}
NOT_FITTED = GAS_ENCODED + ("motor.voltage",)  # structure, or the log's own input
_GAS = {q.name: q for q in GAS_PARAMETERS}
# what separates parameters a log cannot tell apart: (the names, the experiment). The figures are
# relative standard errors of all eight fitted at once from 0.5 s twin logs (docs/explanation/bench-log.md,
# bench/benchlog_identifiability.py)
SEPARATING = (
    (("booster.leak", "leak.tip_gap", "leak.end_gap"),
     "a run with the inlet closed (booster port blanked): the pressure the pump holds there is set by "
     "the clearances and the leaks alone (booster.leak 25 -> 6 %, tip gap 13 -> 8 %, end gap 30 -> 18 %); "
     "a hold test (the pump stopped at a low booster pressure, the check valve closed) gives the booster "
     "leak alone"),
    (("motor.constant", "motor.resistance"),
     "a log that starts with the pump at rest (the inrush gives the resistance, the running current the "
     "constant: both to < 0.5 %), or runs at two supply voltages, or a stalled-rotor current at a low voltage "
     "(motor.resistance alone)"),
    (("mu", "mu_slot", "motor.friction"),
     "a run with the inlet closed, where the vane friction follows the pressures the pump holds and the "
     "motor's friction torque does not (motor.friction 27 -> 9 %, its correlation with mu 0.89 -> 0.65); "
     "a speed column helps a little (27 -> 19 %)"),
    (("valve.cracking",),
     "a pump-down to a lower booster pressure, or a run with the inlet closed (24 -> 17 %): the exhaust "
     "valve's cracking shapes the compression work at low inlet pressure"),
)
JACOBIANS = ("differences", "sensitivities")  # BenchLogProblem's Jacobian (module doc)
CORRELATED = 0.95  # |correlation| above which two estimates are named as hard to separate
WEAK = 0.1  # relative standard error above which an estimate is named as weakly determined


def fit_map(cfg):
    """What parameter_map needs for the pneumatic layout: (index by name, the config's parameter
    vector, the COF ratios mu keeps, the slot COF, the derived defaults that follow their inputs)."""
    from ..kernels.pneumatic import parameter_vector, structure_of

    p0 = parameter_vector(cfg)
    names = [q.name for q in pneumatic_layout(structure_of(cfg))]
    v = dict(zip(names, p0))
    ratios = np.array([v[f"friction.{s}.static"] / max(v[f"friction.{s}.dynamic"], 1e-300)
                       for s in ("housing", "slot")] + [slot_ratio(v)])
    return {n: i for i, n in enumerate(names)}, p0, ratios, v["friction.slot.dynamic"], following(cfg)


class BenchLogProblem(Problem):
    """The pump-down model at a bench log's samples (pressure, interval-mean current and speed),
    each channel divided by its noise sigma; Jacobian by forward differences."""

    KIND = " for a bench log"
    METHOD_TAG = "/bench-log"
    RESIDUAL_UNIT = "noise sigmas"  # each channel divided by its noise sigma
    SPECIAL = COF_ALIASES

    def __init__(self, cfg, log: BenchLog, names, initial=None, hold=None, rtol=BENCH_FIT_RTOL,
                 atol=BENCH_FIT_ATOL, jacobian="differences", step=DIFFERENCE_STEP):
        from ..kernels.pneumatic import kernels

        if cfg.pneumatic is None or not cfg.pneumatic.motor:
            raise ConfigError(f"{cfg.path or cfg.name}: a bench log is fitted with the pump-down model: the config "
                              "needs the gas tables and operation.mode = \"motor\" (spec §8, §10)")
        if jacobian not in JACOBIANS:
            raise ConfigError(f"jacobian must be one of {', '.join(JACOBIANS)}, got '{jacobian}'")
        self.cfg, self.data, self.rtol, self.atol, self.jacobian = cfg, log, rtol, atol, jacobian
        self.step = step  # the forward differences' step, of the parameter's scale
        self.kern = kernels(cfg)
        self._index, self.p0, self._ratios, mu_slot, self._follow = fit_map(cfg)
        self.names = list(names)
        if START_NAME in self.names:  # the start pressure rides last in the vector (BenchModel.split)
            self._index = {**self._index, START_NAME: self.p0.size}
            self.p0 = np.append(self.p0, log.start_pressure())
        if not self.names:
            raise ConfigError("--params names no parameter to fit")
        for n in self.names:
            self._check_name(n)
        if len(set(self.names)) != len(self.names):
            raise ConfigError(f"--params names a parameter twice: {','.join(self.names)}")
        v = dict(zip(self._index, self.p0))
        self.fixed = {"mu": v["friction.housing.dynamic"], "mu_slot": mu_slot}
        self.hold = dict(hold or {})
        initial = initial or {}
        self.x0 = np.array([float(initial.get(n, self.fixed.get(n, v.get(n, 0.0)))) for n in self.names])
        bounds = [(0.5 * v[n], 1.5 * v[n]) if n == START_NAME else _GAS[n].fit_bounds() if n in _GAS else
                  fit_bounds(n, cfg.parameters("constrained").structure) for n in self.names]
        self.lower, self.upper = (np.array(b, dtype=float) for b in zip(*bounds))
        self.t = log.time - log.time[0]
        self.channel_names = list(log.channels())
        omega0 = float(log.speed[0]) if log.speed is not None else 0.0
        self.bench = BenchModel(cfg, log.time, log.voltage, log.start_pressure(), omega0, rtol, atol, self.kern)
        self.measured = self.bench.compared(log.channels())
        # robust sigma of first differences of what is compared (block means: their own), floored
        self.sigma = {c: max(measured_noise(y), CHANNEL_FLOOR * float(np.max(np.abs(y)))) for c, y in self.measured.items()}
        self.y = self.scaled(self.measured)
        self.n_eval = 0
        self.last = None  # the channels of the last simulation (unscaled)
        self._at = None  # (x, model) of the last simulation: a Jacobian at an accepted trial point reuses it

    def keep_at(self, x):  # every sample: `measured` here is the channels' logged values, not a mask
        return None

    def _check_name(self, n):
        if n in NOT_FITTED:
            raise ConfigError(f"--params: '{n}' is not a fit parameter of a bench log"
                              + (" (the log's voltage drives the model)" if n == "motor.voltage" else
                                 " (it selects the model's structure)"))
        if n in self.SPECIAL or n in self._index:
            return
        close = difflib.get_close_matches(n, list(self.SPECIAL) + list(self._index), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ConfigError(f"--params: unknown parameter '{n}'{self.KIND}{hint}")

    def parameter_vector(self, x):
        val = {**self.hold, **dict(zip(self.names, map(float, x)))}
        p = parameter_map(self._index, self.p0, val, self.fixed["mu_slot"], self._ratios, self._follow)
        return np.asarray(p, dtype=float).ravel()

    def simulate(self, x) -> dict:
        """{channel: model samples} (unscaled) at the log's samples with the fitted values x."""
        x = np.asarray(x, dtype=float)
        if self._at is not None and np.array_equal(self._at[0], x):
            self.last = self._at[2]
            return self.last
        return self._simulated([x])[0]

    def _simulated(self, xs) -> list:
        outs = self.bench.channels_many([self.parameter_vector(x) for x in xs])
        self.last = {c: outs[0][c] for c in self.channel_names}
        return [{c: o[c] for c in self.channel_names} for o in outs]

    def scaled(self, ch: dict):
        return np.concatenate([ch[c] / self.sigma[c] for c in self.channel_names])

    def model(self, x):
        x = np.asarray(x, dtype=float)
        if self._at is not None and np.array_equal(self._at[0], x):
            return self._at[1]
        self.n_eval += 1
        ch = self.simulate(x)
        m = self.scaled(ch)
        self._at = (x.copy(), m, ch)
        return m

    def scale_of(self, j, x):
        return max(abs(x[j]), TYPICAL.get(self.names[j], 0.0)) or 1.0

    def difference_step(self, j, x) -> float:
        """Parameter j's forward-difference step at x, away from its upper bound."""
        h = self.step * self.scale_of(j, x)
        return h if x[j] + h <= self.upper[j] else -h

    def model_and_jacobian(self, x, cols=None):
        """The model and its Jacobian: forward sensitivities of one run where the bench model has
        them (bench_model.BenchModel.has_sensitivities), else forward differences (the step away
        from a bound), the perturbed runs integrated at once."""
        x = np.asarray(x, dtype=float)
        cols = list(range(len(self.names)) if cols is None else cols)
        p = self.parameter_vector(x)
        if cols and self.jacobian == "sensitivities" and self.bench.has_sensitivities(p):
            return self._sensitivity_jacobian(x, p, cols)
        m = self.model(x)
        last = self.last
        xs, hs = self.difference_points(x, cols)
        self.n_eval += len(xs)
        ms = [self.scaled(ch) for ch in self._simulated(xs)] if xs else []
        self.last = last
        return m, differences(m, ms, hs)

    def difference_points(self, x, cols) -> tuple[list, list]:
        """The forward-difference Jacobian's points and steps for the columns cols at x."""
        xs, hs = [], []
        for j in cols:
            xj = x.copy()
            xj[j] += self.difference_step(j, x)
            xs.append(xj)
            hs.append(xj[j] - x[j])
        return xs, hs

    def evaluate(self, x):
        """The noise-scaled model at x by one run of its own, touching no cache (for runs in threads)."""
        return self.scaled(self.bench.channels(self.parameter_vector(x)))

    def model_and_loose_jacobian(self, x, loose: "BenchLogProblem", cols=None):
        """(this problem's model at x, the forward-difference Jacobian in the columns cols (all:
        None) whose steps are `loose`'s -- the same log and parameters at a looser tolerance --
        from this model at x), the run at x and the steps' runs at once on the cores, the longest first, each run single-threaded: no more
        threads than default_threads(). The difference's base is the tight run, not a loose one of
        its own: a run less, and the columns as close to the tight ones (docs, bench-log fit). Only
        the direct driver's runs share the cores (each on its own solver memory); CasADi's plugin
        and the reed valve's event-locating runs go one after another."""
        from concurrent.futures import ThreadPoolExecutor

        from ..kernels.scalar import default_threads

        x = np.asarray(x, dtype=float)
        xs, hs = loose.difference_points(x, range(len(loose.names)) if cols is None else cols)
        loose.n_eval += len(xs)
        jobs = [lambda: self.model(x)] + [lambda xj=xj: loose.evaluate(xj) for xj in xs]
        direct = all(pr.bench.has_sensitivities(pr.parameter_vector(x)) for pr in (self, loose))
        with ThreadPoolExecutor(max_workers=min(len(jobs), default_threads()) if direct else 1) as pool:
            done = list(pool.map(lambda job: job(), jobs))
        return done[0], differences(done[0], done[1:], hs)

    def _sensitivity_jacobian(self, x, p, cols):
        from .bench_sens import parameter_directions

        scales = np.array([self.scale_of(j, x) for j in range(len(self.names))])
        D = parameter_directions(self.parameter_vector, x, scales, self.names_index_voltage, cols)
        ch, dch = self.bench.channels_and_jacobian(p, D, scales[cols])
        self.n_eval += 1
        ch = {c: ch[c] for c in self.channel_names}
        m = self.scaled(ch)
        self.last = ch
        self._at = (x.copy(), m, ch)
        J = np.vstack([dch[c] / self.sigma[c] for c in self.channel_names])
        return m, J

    @property
    def names_index_voltage(self):
        return self._index["motor.voltage"]

    def jacobian_text(self, x) -> str:
        """How model_and_jacobian takes the Jacobian at x (the fit's report says it)."""
        if self.jacobian == "sensitivities" and self.bench.has_sensitivities(self.parameter_vector(x)):
            return ("forward sensitivities of the compiled model (CVODES, one run; a vane's reversal in its slot "
                    "as a jump)")
        return "forward differences of the compiled model (one run per parameter)"

    def symbolic_model(self, phi):
        raise ConfigError("--method ipopt fits torque data; a bench log uses gauss-newton or levenberg-marquardt")

    @property
    def dt(self):
        return self.bench.step

    def speed_of(self, x):
        return self.bench.mean_speed

    def angle(self, x):
        return None


def differences(m, ms, hs) -> np.ndarray:
    """The forward-difference Jacobian from the model m, the models ms at the steps hs."""
    return np.column_stack([(mj - m) / h for mj, h in zip(ms, hs)]) if ms else np.zeros((m.size, 0))


def values_vector(cfg, values=None) -> np.ndarray:
    """The runtime parameter vector with `values` (name -> value; mu and config key paths) set."""
    index, p0, ratios, mu_slot, follow = fit_map(cfg)
    return np.asarray(parameter_map(index, p0, dict(values or {}), mu_slot, ratios, follow), float).ravel()


def twin_log(cfg, duration, rate, values=None, noise=0.005, seed=0, voltage=None, speed=False,
             rtol=BENCH_FIT_RTOL, atol=BENCH_FIT_ATOL) -> BenchLog:
    """A bench log generated by the model with known parameter values (name -> value; mu and
    config key paths), for twin experiments: the config's motor.voltage (or `voltage(t)`, an array
    function of time) drives it, and each channel gets white Gaussian noise of `noise` times its
    range (the voltage of its mean). rtol, atol: the integrator's (tighter than the fit's: a twin
    that does not share the fit's integration error)."""
    t = np.arange(int(round(duration * rate)) + 1) / rate
    volt = np.full_like(t, cfg.pneumatic.values["motor.voltage"]) if voltage is None else np.asarray(voltage(t), float)
    p = values_vector(cfg, values)
    ch = BenchModel(cfg, t, volt, cfg.pneumatic.booster_start, rtol=rtol, atol=atol).samples(p)
    rng = np.random.default_rng(seed)
    noisy = {k: a + noise * np.ptp(a) * rng.standard_normal(a.size) for k, a in ch.items()}
    v_noisy = volt + noise * np.mean(volt) * rng.standard_normal(volt.size)
    return BenchLog(t, v_noisy, noisy["current"], noisy["booster_pressure"], noisy["speed"] if speed else None,
                    source="", notes=[f"twin experiment: {values or {}} noise {noise:g} seed {seed}"])


@dataclass
class ChannelFit:
    channel: str
    unit: str
    noise: float  # the sigma the channel is scaled by
    rms: float  # residual RMS in the channel's unit
    fit_percent: float  # NRMSE fit, spec §10

    def as_dict(self):
        return {"rms": self.rms, "fit": self.fit_percent, "noise_sigma": self.noise, "unit": self.unit}


UNITS = {"booster_pressure": "Pa", "current": "A", "speed": "rad/s"}


def channel_fits(prob: BenchLogProblem, fitted: dict) -> dict:
    out = {}
    for c in prob.channel_names:
        y = prob.measured[c]
        out[c] = ChannelFit(c, UNITS[c], prob.sigma[c], float(np.sqrt(np.mean((y - fitted[c]) ** 2))),
                            fit_percent(y, fitted[c]))
    return out


def separation_notes(names, unident, correlation, identified, relative_se=None) -> list[str]:
    """What would separate the parameters this log cannot tell apart: the unidentifiable ones, the
    identified pairs correlated beyond CORRELATED and (relative_se: name -> relative standard
    error) the estimates weaker than WEAK."""
    hard = set(unident)
    weak = [n for n in identified if (relative_se or {}).get(n, 0.0) > WEAK]
    pairs = []
    if correlation is not None:
        for a in range(len(identified)):
            for b in range(a + 1, len(identified)):
                if abs(correlation[a, b]) > CORRELATED:
                    pairs.append((identified[a], identified[b], float(correlation[a, b])))
                    hard.update((identified[a], identified[b]))
    notes = []
    if unident:
        notes.append(f"this log cannot separate {', '.join(unident)}")
    for a, b, c in pairs:
        notes.append(f"{a} and {b} are correlated {c:+.3f}: the log tells their combination better than either")
    if weak:
        notes.append("this log determines " + ", ".join(f"{n} to {100 * relative_se[n]:.2g} %" for n in weak)
                     + " only (a standard error above " + f"{100 * WEAK:.0f} % of the value)")
        hard.update(weak)
    for group, experiment in SEPARATING:
        if hard & set(group):
            notes.append(f"to separate {', '.join(n for n in group if n in hard or n in names)}: {experiment}")
    return notes


@dataclass(kw_only=True)
class BenchFit:
    """The bench-log identification: the IdentificationResult (estimates, correlation, history in
    noise-scaled units) and per channel the fit, the measured and fitted samples."""

    result: object
    channels: dict  # name -> ChannelFit
    measured: dict
    fitted: dict
    time: dict  # channel -> the times of its compared values
    notes: list = field(default_factory=list)
    jacobian: str = "forward differences of the compiled model (one run per parameter)"
    start: str = "the config's values"
    ripple: object = None  # current_ripple.RippleFit: mu from the vane-passing ripple, or why not

    def problems(self) -> list[str]:
        """Why this fit is not a usable estimate (the command exits 1): not converged, a parameter
        on its bound, parameters the log cannot separate (the notes say what would)."""
        r = self.result
        out = [] if r.converged else [f"NOT converged ({r.message})"]
        out += [f"{n} ended on its bound {b:g} (a unit mistake, a wrong configuration or an effect the model "
                "lacks; the interval is not valid)" for n, b in r.on_bound]
        apart = [n for n in r.unidentifiable if n not in r.no_effect]
        if apart:
            out.append(f"not identifiable from this log: {', '.join(apart)} (see the notes for the experiment "
                       "that separates them, or fit fewer parameters)")
        return out

    def to_json(self) -> dict:
        d = self.result.to_json()
        d["fit"] = {c: f.as_dict() for c, f in self.channels.items()}
        d["rms_unit"] = "noise sigmas (each channel divided by its noise sigma)"
        d.update(separability=self.notes, jacobian=self.jacobian, start=self.start)
        if self.ripple is not None:
            d["ripple"] = self.ripple.to_json()
        return d

    def __str__(self):
        r = self.result
        its = len(r.iterations) - 1
        lines = [f"bench-log identification ({r.method}): {'converged' if r.converged else 'NOT converged'} after "
                 f"{its} iterations, weighted residual RMS {r.rms:.4g} noise sigmas, {r.wall_time:.1f} s"]
        if r.provenance:
            pv = r.provenance
            lines.append(f"  from {pv['config']} and " + ", ".join(
                f"{d['name']} (sha256 {d['sha256'][:12]})" for d in pv["data"]))
        for e in r.estimates.values():
            if e.identifiable and e.value is not None:
                rel = f" ({100 * e.stderr / abs(e.value):.2g} %)" if e.value else ""
                lines.append(f"  {e.name:<22} {e.value:.6g} ± {e.stderr:.3g}{rel}  (95%: {e.lower95:.6g} .. "
                             f"{e.upper95:.6g}; start {e.initial:.6g})")
            else:
                lines.append(f"  {e.name:<22} not identifiable from this log (held at {e.initial:.6g})")
        for c in self.channels.values():
            lines.append(f"  {c.channel:<17} fit {c.fit_percent:6.2f} %, residual RMS {c.rms:.4g} {c.unit} "
                         f"(noise sigma {c.noise:.3g} {c.unit})")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def fitting(params=None):
    """An interruption names the fit, not only the pump-down run it was in (interrupt.stage)."""
    what = ", ".join(params) if params else "the bench log's parameters"
    return interrupt.stage(f"in a fit of {what} before its first iteration ended")


def identify_bench(cfg, log: BenchLog, params=("mu", "booster.leak", "motor.resistance"), method="gauss-newton",
                   initial=None, max_iter=30, relaxation=1.0, progress=None, start="maps", rtol=BENCH_FIT_RTOL,
                   atol=BENCH_FIT_ATOL, ripple=True, jacobian="differences", fit_start=True,
                   continuation=True) -> BenchFit:
    """Fit `params` (config key paths, mu, mu_slot) of the pump-down model to a bench log.
    start "maps": a fit of the fast model from the pump's cycle-averaged maps, then full-model
    steps (bench_fast.fast_then_full); "config": the full model's Gauss-Newton from the config's
    values (also where the maps' start leaves a parameter the log cannot determine). Parameters the
    log cannot determine (no effect, or a near-null direction of the noise-scaled Jacobian) get no
    number and the note says what experiment would separate them. rtol, atol: the full model's
    integration. ripple: then mu from the current's vane-passing ripple where the log resolves it
    (current_ripple). jacobian: the full model's, "differences" or "sensitivities" (module doc).
    fit_start: the booster's pressure at the first sample (START_NAME) is fitted with the others
    (a nuisance parameter, reported last): the log's own estimate of it carries its noise, and
    the model started there biases the leak and the resistance by several standard errors (docs:
    bench-log fit); False keeps the estimate (and its bias). With jacobian "sensitivities" the
    start's column is an initial-condition sensitivity of the same run. continuation (the maps'
    start, forward differences, rtol below CONTINUATION_RTOL): the Jacobian's (the covariance's)
    difference steps at CONTINUATION_RTOL from the base run at rtol, the steps and the convergence
    test at rtol (bench_fast.fast_then_full); the sensitivities do not survive the loose tolerance
    (docs)."""
    from .bench_fast import maps_jacobian_text
    from .fit import fit_identifiable
    from .identifiability import to_fix
    from .optimiser import Optimiser

    if method == "ipopt":
        raise ConfigError("--method ipopt fits torque data; a bench log uses gauss-newton or levenberg-marquardt")
    if start not in ("maps", "config"):
        raise ConfigError(f"start must be 'maps' or 'config', got '{start}'")
    optimiser = Optimiser(method, relaxation, max_iter, progress)
    wall0 = _time.perf_counter()
    params = list(params) + ([START_NAME] if fit_start and START_NAME not in params else [])
    prob = BenchLogProblem(cfg, log, params, initial, rtol=rtol, atol=atol, jacobian=jacobian)
    x_start, how, loose_runs = prob.x0.copy(), "the config's values", 0
    if start == "maps":
        loose = (BenchLogProblem(cfg, log, params, initial, rtol=CONTINUATION_RTOL, atol=atol * CONTINUATION_RTOL / rtol,
                                 step=CONTINUATION_STEP)
                 if continuation and jacobian == "differences" and rtol < CONTINUATION_RTOL else None)
        out, x_start, how = _from_maps(prob, loose, max_iter, progress)
        loose_runs = 0 if loose is None else loose.n_eval
        if not any(to_fix(prob.names, out.jacobian, out.x, prob.y - out.residual)):
            res = _result(prob, prob, out, [], [], loose_runs, log, cfg, wall0, method)
            fit = _bench_fit(prob, res, out.x, how)
            fit.jacobian = maps_jacobian_text(prob, loose, out.x)
            return _checked(_with_ripple(fit, cfg, log, prob, prob, out.x) if ripple else fit, cfg, log)

    def reduced(active, fixed, unident):
        return BenchLogProblem(cfg, log, active, {n: fixed[n] for n in active}, {n: fixed[n] for n in unident},
                               rtol, atol, jacobian)

    fit = fit_identifiable(prob, x_start, optimiser, reduced)
    fitted_prob = prob if fit.outcome is None else fit.prob
    res = _result(prob, fitted_prob, fit.outcome, fit.unident, fit.no_effect, fit.evaluations + loose_runs, log, cfg,
                  wall0, method)
    x = prob.x0 if fit.outcome is None else fit.outcome.x
    bench = _bench_fit(fitted_prob, res, x, how, prob.names, fit.unident)
    return _checked(_with_ripple(bench, cfg, log, prob, fitted_prob, x) if ripple else bench, cfg, log)


def _from_maps(prob, loose, max_iter, progress):
    """(FitOutcome, x of the fast fit, how the fit started) of the maps' start (bench_fast)."""
    from .bench_fast import FastBenchModel, fast_then_full

    fast = FastBenchModel(prob.cfg, prob.bench, prob.data.booster_pressure, prob.names, prob.parameter_vector, prob.x0,
                          prob.scale_of)
    out, x_fast = fast_then_full(prob, fast, prob.x0, max_iter, progress, loose)
    how = (f"the fast model's fit (cycle-averaged maps, {len(fast.slopes) + 1} sets), then "
           f"{len(out.history) - 1} full-model steps from there" + ("" if loose is None else
           f" (the Jacobian's difference steps at rtol {loose.rtol:g}: {loose.n_eval} runs)"))
    return out, x_fast, how


def _checked(bench: BenchFit, cfg, log) -> BenchFit:
    """bench with what the log's own checks say about the figures (a start above the atmosphere)
    and what reading it did (spikes replaced, time from stamps)."""
    above = start_above_atmosphere(log, cfg)
    bench.notes[:0] = ([above] if above else []) + [f"the log: {n}" for n in log.notes]
    return bench


def _result(prob, fitted_prob, out, unident, no_effect, evaluations, log, cfg, wall0, method):
    """The IdentificationResult of a bench-log fit (out: the optimiser's outcome, None: nothing
    identifiable)."""
    from .result import Estimate, IdentificationResult, fit_estimates, provenance, bounds_reached

    x0 = dict(zip(prob.names, prob.x0))
    if out is None:
        r = prob.y - prob.model(prob.x0)
        est, corr, history, converged, message, on_bound = {}, None, [], False, "nothing identifiable", []
        intervals = None
    else:
        x, r, history = np.asarray(out.x, float), out.residual, out.history
        est, corr, intervals = fit_estimates(fitted_prob.names, x, [x0[n] for n in fitted_prob.names], r, out.jacobian,
                                             fitted_prob.y, [(c, fitted_prob.measured[c].size) for c in fitted_prob.channel_names])
        converged, message, on_bound = out.converged, out.message, bounds_reached(fitted_prob, x)
    for n in unident:
        est[n] = Estimate(n, None, None, None, None, x0[n], identifiable=False)
    res = IdentificationResult(
        estimates={n: est[n] for n in prob.names}, iterations=history, rms=float(np.sqrt(np.mean(r ** 2))),
        converged=converged, message=message, correlation=corr, diagnostics={}, method=method + prob.METHOD_TAG,
        wall_time=0.0, unidentifiable=unident, time=log.time, on_bound=on_bound, no_effect=no_effect,
        n_evaluations=prob.n_eval + evaluations + (fitted_prob.n_eval if fitted_prob is not prob else 0),
        intervals=intervals)
    res.provenance = provenance(cfg, _AsData(log), prob.kern)
    res.wall_time = _time.perf_counter() - wall0
    if unident:
        res.message += ("; " if res.message else "") + f"not identifiable from this log: {', '.join(unident)}"
    return res


def _bench_fit(fitted_prob, res, x, how, names=None, unident=()) -> BenchFit:
    fitted = fitted_prob.simulate(x)
    identified = list(fitted_prob.names) if res.correlation is not None else []
    rel = {n: e.stderr / abs(e.value) for n, e in res.estimates.items() if e.identifiable and e.value}
    notes = separation_notes(names or fitted_prob.names, list(unident), res.correlation, identified, rel)
    notes += res.interval_notes()
    return BenchFit(result=res, channels=channel_fits(fitted_prob, fitted), measured=fitted_prob.measured,
                    fitted=fitted, time={c: fitted_prob.bench.times(c) for c in fitted}, notes=notes, start=how,
                    jacobian=fitted_prob.jacobian_text(x))


def _with_ripple(bench: BenchFit, cfg, log, prob, fitted_prob, x) -> BenchFit:
    """bench with mu from the current's vane-passing ripple at the fitted values (or why not)."""
    values = {"mu": prob.fixed["mu"], **fitted_prob.hold, **dict(zip(fitted_prob.names, x))}
    bench.ripple = bench_ripple(cfg, log, lambda v: values_vector(cfg, v), values,
                                bench.result.estimates.get("mu"), prob.kern)
    bench.notes += bench.ripple.notes()
    return bench


class _AsData:
    """What provenance() reads of a measurement: its source (hashed) and, without one, samples."""

    def __init__(self, log: BenchLog):
        self.source, self.time = log.source, log.time
        self.torque = np.concatenate([log.voltage, log.current, log.booster_pressure])
        self.speed = log.speed
        self.angle = None


