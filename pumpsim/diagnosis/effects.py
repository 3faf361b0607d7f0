"""The effect library: one declaration per effect the workflow can name (its parameters, how it
enters the model, its probes and its physical ranges), and the candidates they make."""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass


from ..config import PumpConfig
from ..identification import base_name
from ..identification.problem import slot_ratio
from ..model_spec.parameters import implausible

from .estimates import to_polar
from .state import State


def clearance(cfg: PumpConfig) -> float:
    """Smallest radial gap between rotor and housing [m] (nominal housing, no defect)."""
    v = cfg.values
    return min(v["housing.a"], v["housing.b"]) - v["rotor.radius"]


def harmonic_pair(k: int) -> list:
    """Two housing-harmonic slots of order k, phases 0 and pi/(2k), zero amplitudes a and b:
    a cos(k phi) + b sin(k phi) = A cos(k (phi - gamma)) is linear in (a, b), so the fit needs no
    phase wrapping and the absent defect (a = b = 0) is a regular point."""
    return [[k, 0.0, 0.0], [k, 0.0, math.pi / (2 * k)]]


def with_harmonic_pair(cfg: PumpConfig, k: int) -> PumpConfig:
    """The config with a harmonic pair of order k added (harmonic_pair)."""
    return cfg.with_harmonics(cfg.harmonics + harmonic_pair(k))


def is_harmonic_amplitude(key: str) -> bool:
    return key.startswith("housing.harmonics.") and key.endswith(".amplitude")


def _out_of_round_implausible(cfg: PumpConfig, v: dict, context: dict) -> list:
    """An out-of-round of one order is a pair of harmonic slots: their hypot is the amplitude."""
    amps = {}
    for k_, x in v.items():
        if is_harmonic_amplitude(k_):
            j = int(k_.split(".")[2])
            order = cfg.harmonics[j][0] if j < len(cfg.harmonics) else 0
            amps.setdefault(order, [k_, 0.0])[1] = math.hypot(amps.get(order, [k_, 0.0])[1], x)
    out = []
    for order, (k_, A) in amps.items():
        out += [m.replace(k_, f"out-of-round k={order:g} amplitude", 1) for m in implausible({k_: A}, context=context)]
    return out


def _vane_spread_implausible(cfg: PumpConfig, v: dict, context: dict) -> list:
    """A vane's COF is mu times its factor: checked against the COF's range."""
    mu = v.get("mu", cfg.values["friction.housing.dynamic"])
    out = []
    for i in range(cfg.vanes):
        f = v.get(f"effects.vane_friction_factor.{i}")
        if f is not None:
            out += [m.replace("friction.housing.dynamic", f"vane {i} COF (mu x factor)", 1)
                    for m in implausible({"friction.housing.dynamic": f * mu})]
    return out


@dataclass(frozen=True)
class PolarForm:
    """How an effect fitted as a pair a cos(k x) + b sin(k x) (linear in a, b: no phase wrapping, a
    regular absent point) reads as an amplitude and a phase: labels, display scale and unit."""

    title: str  # the effect at order k, e.g. "out-of-round" -> "out-of-round k = 4"
    amplitude: str  # in a step's parameter list
    amplitude_meaning: str  # in the final-parameter table
    scale: float  # display factor of the amplitude
    unit: str  # display unit of the amplitude
    phase: str
    phase_meaning: str
    per_order: bool = False  # the physical phase is the pair's phase over k (an angle on the housing)

    def describe(self, res, names, k) -> dict:
        """{"amplitude", "phase"} ({value, stderr} each, SI) of the pair `names` fitted in `res`."""
        A, ph = to_polar(res, names, k)
        if self.per_order:
            ph = {"value": ph["value"] / k, "stderr": ph["stderr"] / k}
        return {"amplitude": A, "phase": ph}


OUT_OF_ROUND_FORM = PolarForm("out-of-round", "radial amplitude", "radial amplitude A_k", 1e6, "µm", "phase γ",
                              "phase γ_k (A cos k(α − γ))", per_order=True)
RIPPLE_FORM = PolarForm("speed ripple", "amplitude", "amplitude (ω = ω0 (1 + A cos(kθ + φ)))", 100, "% of ω0",
                        "phase", "phase φ")


def _relative(cfg: PumpConfig, value: float) -> float:
    return abs(value)


@dataclass(frozen=True)
class Effect:
    """One effect of the library, declared once: what it is, its fitted parameters (per shaft
    order), how it enters the model, how its score test probes it, how its parameters map onto
    the registry's plausibility ranges (model_spec.parameters) and how they read. The workflow,
    the result and the report loop over these declarations: a new effect is one declaration here
    plus its term in the model (identification/problem.py)."""

    name: str  # its name in the JSON (spec section 7)
    params: Callable[[PumpConfig, int | None], list]  # (config, order) -> fitted names for Problem
    description: str = ""  # one line: what a named effect means for the pump
    orders: Callable[[PumpConfig], Iterable] = lambda cfg: (None,)  # shaft orders tried (None: no order)
    min_vanes: int = 1
    harmonic_pair: bool = False  # enters the config as a harmonic pair of its order
    ripple: bool = False  # its order is the drive's speed-ripple order
    # geometric defects of a pump with identical, equally spaced vanes can leave the torque
    # unchanged to first order (an eccentric housing with N >= 2: the per-vane changes at odd orders
    # cancel in the sum); their score test then uses the second-order terms, and the one-step
    # start is kept inside the clearance
    symmetric: bool = False
    # step of the second-order probes (state, problem) -> h; None: first-order score test only
    probe_step: Callable | None = None
    one_sided: bool = False  # a parameter >= 0 at its absent value 0: one-sided probes
    # non-smooth (friction reversals move): also a grid of finite sizes where the first order is
    # blind in some direction (screen.score_test)
    finite_probes: bool = False
    start_floor: tuple = ()  # (name, least start value) pairs for the refit
    polar: PolarForm | None = None  # a harmonic pair read as amplitude and phase
    claims: Callable[[str], bool] | None = None  # names whose range `implausible` checks instead of the registry
    implausible: Callable | None = None  # (config, values, context) -> reasons
    # (config, current values) -> its parameters' absent values where they are not the config's
    absent: Callable | None = None
    # (config, value) -> the standard error above which an estimate is not a result (None: always one)
    resolution: Callable[[PumpConfig, float], float] | None = None


def _slot_cof_tied(cfg: PumpConfig, values: dict) -> dict:
    """The slot COF while slot_friction is absent: mu's, in the configured slot/housing proportion
    (what every fit of mu alone does: identification/problem.py parameter_map)."""
    return {"mu_slot": values.get("mu", cfg.values["friction.housing.dynamic"]) * slot_ratio(cfg.values)}


EFFECTS = (
    Effect("rotor_eccentricity", lambda cfg, k: ["housing.center.0", "housing.center.1"],
           "the rotor axis is off the housing centre", symmetric=True,
           probe_step=lambda state, prob: probe_scale(state), finite_probes=True,
           resolution=lambda cfg, v: clearance(cfg)),
    Effect("housing_out_of_round",
           lambda cfg, k: [f"housing.harmonics.{j}.amplitude" for j in (len(cfg.harmonics), len(cfg.harmonics) + 1)],
           "the bore has k lobes (k = 2: oval)", orders=lambda cfg: range(2, 9), harmonic_pair=True,
           symmetric=True, probe_step=lambda state, prob: probe_scale(state), polar=OUT_OF_ROUND_FORM,
           claims=is_harmonic_amplitude, implausible=_out_of_round_implausible,
           resolution=lambda cfg, v: clearance(cfg)),
    Effect("speed_ripple", lambda cfg, k: ["ripple_cos", "ripple_sin"], "the drive's speed pulses k times a revolution",
           orders=lambda cfg: range(1, 2 * cfg.vanes + 1), ripple=True, polar=RIPPLE_FORM,
           resolution=lambda cfg, v: 0.05),
    Effect("torque_offset", lambda cfg, k: ["torque_offset"], "the torque sensor reads a constant offset"),
    # one-sided (T >= 0): probe a twentieth of a radian of lag; and a line of finite lags (a lag of
    # a sample or more, 0.3 ms at 5 kHz on an independent record, is far outside its quadratic model)
    Effect("sensor_lag", lambda cfg, k: ["lag"], "the torque sensor lags (first-order low-pass)",
           probe_step=lambda state, prob: 0.05 / prob.speed_of(prob.x0), one_sided=True,
           start_floor=(("lag", 1e-6),), finite_probes=True, resolution=_relative),
    Effect("viscous_tip_friction", lambda cfg, k: ["effects.viscous_tip_friction"],
           "the vane tips see a friction force growing with slip speed", resolution=_relative),
    # a vane of another material or finish: its tip and slot COFs scaled together (vane 0 is the
    # reference; the reported mu is the mean over the vanes)
    Effect("vane_friction_spread", lambda cfg, k: [f"effects.vane_friction_factor.{i}" for i in range(1, cfg.vanes)],
           "the vanes' COFs differ (another material or finish)", min_vanes=2,
           implausible=_vane_spread_implausible, resolution=_relative),
    # the configured slot/tip COF ratio is off (the slot COF is the one rigs rarely measure; a tip
    # COF rising with slip speed looks like this at one speed): mu_slot free, its range a COF's
    Effect("slot_friction", lambda cfg, k: ["mu_slot"], "the slot COF is not the configured share of the tip's",
           absent=_slot_cof_tied, resolution=_relative),
)
BY_NAME = {e.name: e for e in EFFECTS}


NOT_RANGED = ("theta0", "speed", "delay")  # measurement parameters without a plausibility range


def plausible(cfg: PumpConfig, values: dict, torque_rms: float, mean_torque: float) -> list:
    """Reasons why fitted values leave their physical range ([] = all plausible). `values` holds
    fitted names (joint suffixes allowed) -> value. The ranges and their physics are declared once,
    with each parameter, in the registry (model_spec.parameters: `plausible`); how this workflow's
    parametrisation maps onto them is declared with each effect (an out-of-round of one order is a
    pair of harmonic slots, a vane's COF is mu times its factor)."""
    v = {base_name(k): x for k, x in values.items() if x is not None}
    context = {"clearance": clearance(cfg), "speed": cfg.speed or 1.0, "vanes": cfg.vanes,
               "housing_a": cfg.values["housing.a"], "torque_rms": torque_rms, "mean_torque": mean_torque}
    plain = {k_: x for k_, x in v.items()
             if k_ not in NOT_RANGED and not any(e.claims is not None and e.claims(k_) for e in EFFECTS)}
    out = implausible(plain, context=context)
    for e in EFFECTS:
        if e.implausible is not None:
            out += e.implausible(cfg, v, context)
    return out


@dataclass(frozen=True)
class Candidate:
    """An effect of the library at one shaft order (None: an effect without an order)."""

    kind: Effect
    params: tuple  # parameter names for Problem
    order: int | None = None  # shaft order (out-of-round, speed ripple)

    @property
    def effect(self) -> str:
        return self.kind.name

    @property
    def symmetric(self) -> bool:
        return self.kind.symmetric

    @property
    def ripple_order(self) -> int | None:
        return self.order if self.kind.ripple else None

    @property
    def label(self):
        return f"{self.effect}(k={self.order})" if self.order else self.effect

    def config(self, cfg: PumpConfig) -> PumpConfig:
        return with_harmonic_pair(cfg, self.order) if self.kind.harmonic_pair else cfg

    def problem(self, state: "State"):
        """The state's problem with this candidate's parameters added at their absent values."""
        if self.kind.absent is not None:
            state = State(state.cfg, state.data, state.names,
                          {**self.kind.absent(state.cfg, state.values), **state.values}, state.ripple_order)
        return state.problem(self.params, cfg=self.config(state.cfg), ripple_order=self.ripple_order)


def candidates(cfg: PumpConfig, added: set, detected: Iterable = ()) -> list:
    """The library's candidates, plus a speed ripple at each of the `detected` orders (above the
    library's: detected_ripple_orders)."""
    return [Candidate(e, tuple(e.params(cfg, k)), k) for e in EFFECTS if e.name not in added and cfg.vanes >= e.min_vanes
            for k in list(e.orders(cfg)) + (list(detected) if e.ripple else [])]


def probe_scale(state: State) -> float:
    """Probe step for geometric defects: 1e-3 of the housing size (tens of micrometres)."""
    v = state.cfg.values
    return 1e-3 * max(v.get("housing.a", 0.0), v.get("housing.b", 0.0), 1e-3)


def absent_values(run, names) -> dict:
    """The absent values: an added harmonic pair at zero amplitude, a config key at its configured
    value, a ripple, lag or offset at zero."""
    return {n: 0.0 if is_harmonic_amplitude(n) or n not in run.cfg.values else run.cfg.values[n] for n in names}


def effect_of(name, cfg) -> Effect | None:
    """The effect of the library whose parameter the fitted `name` is (as the library declares its
    parameters: an out-of-round's harmonic amplitude, the housing centre, the ripple pair, the
    lag); None for a baseline parameter."""
    n = base_name(name)
    for e in EFFECTS:
        if (e.claims is not None and e.claims(n)) or any(n in e.params(cfg, k) for k in e.orders(cfg)):
            return e
    return None


def owner_of(name, cfg) -> str:
    """A fitted name as the engineer reads it: a named effect's parameter as that effect, a
    baseline parameter as itself."""
    e = effect_of(name, cfg)
    return base_name(name) if e is None else e.name
