"""Study file (spec §9): a base config, the varied config keys and how, operating points, outputs,
spec limits and, for optimisation, an objective and constraints.

Everything is checked before any work starts; every rejection names the study key and the limit.
A design is the base config's TOML table with the varied keys replaced, validated again by
`config_from_dict`, so a derived default (vane.inertia = m (L² + h²)/12 when the config does not
give it) follows its inputs, and an impossible value is a per-design status, not a crash.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..config import config_from_dict, schema
from ..errors import ConfigError
from ..limits import limits_table
from ..model_spec.housings import COMPILED, config_key
from .outputs import BOOL_OUTPUTS, OUTPUTS
from .pneumatic import GAS_OUTPUTS, check_gas_outputs
from .sampling import DISTRIBUTIONS, SAMPLERS, Variable, parse_variable

MODELS = ("constrained", "contact")
SPEED_KEY = "operation.speed"
_STUDY_KEYS = {"config", "function", "sampler", "samples", "seed", "speeds", "outputs", "model",
               "samples_per_revolution", "scheduler", "workers", "batch_size", "revolution_samples",
               "revolutions", "booster_pressure"}
_TOP_KEYS = {"study", "vary", "limits", "objective", "constraints", "optimize", "sensitivity"}


@dataclass
class Study:
    path: str
    base: dict  # the base config's TOML table (empty for an analytic function)
    config_path: str | None
    variables: list  # [Variable]
    sampler: str = "sobol"
    samples: int = 64
    seed: int = 0
    speeds: list | None = None  # rad/s; None: the config's (or the varied operation.speed)
    outputs: list = field(default_factory=lambda: list(OUTPUTS))
    model: str = "constrained"
    revolution_samples: int = 360
    limits: dict = field(default_factory=dict)  # output -> (lower or None, upper or None)
    objective: list = field(default_factory=list)  # outputs to minimise (2+: Pareto front)
    constraints: dict = field(default_factory=dict)  # output -> (lower, upper)
    optimize: dict = field(default_factory=dict)  # method, iterations, population, ...
    sensitivity: dict = field(default_factory=dict)  # method, samples, ...
    scheduler: str | None = None
    workers: int | None = None
    batch_size: int | None = None
    function: str | None = None  # analytic verification function instead of the pump
    revolutions: int | None = None  # contact model: revolutions simulated (the last is reported)
    booster_pressure: float | None = None  # Pa: the gas outputs' operating point (None: none asked)
    raw: dict = field(default_factory=dict)  # the study file's table (for the hash)
    warnings: list = field(default_factory=list)  # e.g. varied values outside plausible ranges

    @property
    def base_speed(self) -> float:
        """The base config's speed [rad/s] (NaN for an analytic function)."""
        return base_value(self.base, SPEED_KEY) if self.base else math.nan

    @property
    def keys(self) -> list[str]:
        return [v.key for v in self.variables]

    def study_hash(self) -> str:
        """Hash of everything that decides the result table: the study and the base config."""
        payload = json.dumps({"study": self.raw, "base": self.base, "function": self.function},
                             sort_keys=True, default=str)
        return hashlib.sha256(payload.encode()).hexdigest()[:20]

    def design_dict(self, values: dict) -> dict:
        """The base config's table with `values` (key path -> number) applied."""
        return apply_values(self.base, values)


def _num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def schema_leaf(key: str):
    """The schema entry of a config key path ('num', 'int' or a list index), or None."""
    node = schema()
    parts = key.split(".")
    for i, part in enumerate(parts):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
        if isinstance(node, tuple):
            typ = node[0]
            rest = parts[i + 1:]
            if typ in ("num", "int") and not rest:
                return typ
            if typ == "list" and rest and all(r.isdigit() for r in rest):
                return "num"
            return None
    return None


def config_key_ok(key: str) -> bool:
    return key == SPEED_KEY or schema_leaf(key) is not None


def get_value(table: dict, key: str):
    node = table
    for part in key.split("."):
        if isinstance(node, list):
            i = int(part)
            if i >= len(node):
                return None
            node = node[i]
        elif isinstance(node, dict):
            if part not in node:
                return None
            node = node[part]
        else:
            return None
    return node


def apply_values(base: dict, values: dict) -> dict:
    d = dict(base)  # copy only the tables and lists on the changed paths (a design is built per row)
    for key, val in values.items():
        if schema_leaf(key) == "int":
            val = int(round(val))  # the design matrix holds floats
        parts = key.split(".")
        node = d
        for j, part in enumerate(parts[:-1]):
            nxt = parts[j + 1]
            if isinstance(node, list):
                node[int(part)] = copy.copy(node[int(part)])
                node = node[int(part)]
            else:
                if part not in node:
                    node[part] = [0.0, 0.0] if key.startswith("housing.center") else ({} if not nxt.isdigit() else [])
                node[part] = copy.copy(node[part])
                node = node[part]
        last = parts[-1]
        if isinstance(node, list):
            i = int(last)
            while len(node) <= i:
                node.append(0.0)
            node[i] = val
        else:
            node[last] = val
        if key == SPEED_KEY:  # the varied speed replaces a speed given in rpm
            d["operation"] = {k: v for k, v in d.get("operation", {}).items() if k != "speed_rpm"}
            d["operation"][key.split(".")[1]] = val
        if key == "operation.speed_rpm":
            d["operation"] = {k: v for k, v in d.get("operation", {}).items() if k != "speed"}
            d["operation"]["speed_rpm"] = val
    return d


def base_value(base: dict, key: str):
    """The base config's value of a key (a derived or default value from the validated config)."""
    v = get_value(base, key)
    if _num(v):
        return float(v)
    cfg = config_from_dict(base)
    if key == SPEED_KEY:
        return float(cfg.speed)
    for target in COMPILED:  # a housing shape's key (housing.radius)
        path, factor = config_key(cfg.shape, target)
        if path == key != target:
            return cfg.values[target] / factor
    if key in cfg.values:
        return float(cfg.values[key])
    return None


def key_targets(base: dict, key: str, value) -> list[str]:
    """What a key moves in the model: the parameter-registry entries (model_spec.parameters) whose
    value changes when the key does (housing.radius: housing.a and housing.b; vane.mass: vane.mass
    and, when the config does not give it, the derived vane.inertia), 'speed' or 'structure'.
    An empty list: the key does not reach the constrained model (e.g. contact.*)."""
    v0 = float(value) if value is not None else 0.0
    v1 = v0 + 1 if schema_leaf(key) == "int" else (v0 * (1 + 1e-3) if v0 else 1e-6)
    try:
        a = config_from_dict(apply_values(base, {key: v0}))
        b = config_from_dict(apply_values(base, {key: v1}))
    except ConfigError as e:
        raise ConfigError(f"vary.\"{key}\": {e}") from None
    if a.structure_for("constrained") != b.structure_for("constrained"):
        return ["structure"]
    pa, pb = a.parameters("constrained").values, b.parameters("constrained").values
    out = [n for n in pa if pa[n] != pb.get(n)]
    ga, gb = (c.pneumatic.values if c.pneumatic is not None else {} for c in (a, b))
    out += [n for n in ga if ga[n] != gb.get(n) and n not in out]  # the gas model's (spec §8)
    if key == "rotor.width" and "rotor.width" not in out:
        out.append("rotor.width")  # the tip's contact area (max_tip_pv)
    if a.speed != b.speed:
        out.append("speed")
    return out


def plausibility_warnings(base: dict, var) -> list[str]:
    """Registry plausibility (model_spec.parameters.implausible) at the ends of a key's range: its
    smallest and largest value, or its distribution's 0.1 % and 99.9 % quantiles."""
    from ..model_spec.parameters import implausible

    if var.values is not None:
        ends = [min(var.values), max(var.values)]
    elif var.dist is not None:
        ends = [float(var.dist.ppf(0.001)), float(var.dist.ppf(0.999))]
    else:
        ends = list(var.bounds or ())
    out = []
    for x in ends:
        try:
            cfg = config_from_dict(apply_values(base, {var.key: x}))
        except ConfigError:
            continue  # an impossible value is that design's status, reported per design
        names = [n for n in key_targets(base, var.key, x) if n in cfg.values]
        out += [f"vary.\"{var.key}\" reaches {m}" for m in implausible({n: cfg.values[n] for n in names})]
    return out


def _read_toml(path, what) -> dict:
    try:
        return tomllib.loads(Path(path).read_text())
    except OSError as e:
        raise ConfigError(f"{what}: cannot read '{path}': {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{what} '{path}' is not valid TOML: {e}") from None


def load_study(path) -> Study:
    """Read and check a study file (TOML): its base config (relative to the file), the varied keys,
    sampler, limits, objective and method settings. Every rejection is a `ConfigError` naming the key."""
    p = Path(path)
    return study_from_dict(_read_toml(p, "study"), base_dir=p.parent, path=str(p))


def _int_setting(st, key, default, lo, hi, what):
    v = st.get(key, default)
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        raise ConfigError(f"study.{key} must be {what}, got {v!r}")
    return v


def _run_settings(st, function, base_cfg) -> tuple:
    """(sampler, samples, seed, model, revolutions, revolution_samples) of the [study] table."""
    sampler = st.get("sampler", "sobol")
    if sampler not in SAMPLERS:
        raise ConfigError(f"study.sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    samples = st.get("samples", 64)
    if not isinstance(samples, int) or isinstance(samples, bool) or samples < 1:
        raise ConfigError(f"study.samples must be an integer >= 1, got {samples!r}")
    if samples > 10_000_000:
        raise ConfigError(f"study.samples must be <= 10,000,000, got {samples}")
    seed = _int_setting(st, "seed", 0, 0, float("inf"), "an integer >= 0")
    model = st.get("model", "constrained")
    if model not in MODELS:
        raise ConfigError(f"study.model must be 'constrained' or 'contact', got {model!r}")
    if model == "contact" and function is None and not base_cfg.contact_given:
        raise ConfigError("study.model = \"contact\" needs [contact.housing] with a stiffness in the config")
    revolutions = _int_setting(st, "revolutions", None, 2, 1000, "an integer in [2, 1000]")
    nrev = st.get("revolution_samples", st.get("samples_per_revolution", 360))
    if not isinstance(nrev, int) or isinstance(nrev, bool) or not 8 <= nrev <= 100_000:
        raise ConfigError(f"study.revolution_samples must be an integer in [8, 100000], got {nrev!r}")
    return sampler, samples, seed, model, revolutions, nrev


def _outputs_and_limits(raw, st, names, base, base_cfg) -> tuple:
    """(outputs, limits, constraints, objective), every output name checked."""
    outputs = st.get("outputs", _available(names, base, base_cfg))
    if not isinstance(outputs, list) or not outputs:
        raise ConfigError("study.outputs must be a non-empty list of output names")
    for o in outputs:
        if o not in names:
            raise ConfigError(f"study.outputs: unknown output {o!r} (one of {', '.join(names)})")
    limits = limits_table(raw.get("limits", {}), "limits")
    for o in limits:
        _check_numeric_output(o, f"limits.{o}", names)
    constraints = limits_table(raw.get("constraints", {}), "constraints")
    for o in constraints:
        _check_numeric_output(o, f"constraints.{o}", names)
    return list(outputs), limits, constraints, _parse_objective(raw.get("objective", {}), names)


def study_from_dict(raw: dict, base_dir=".", path="<study>") -> Study:
    from .analytic import FUNCTIONS

    st = _study_table(raw)
    function = st.get("function")
    base, cfg_path, base_cfg = _base_config(st, function, base_dir, FUNCTIONS)
    sampler, samples, seed, model, revolutions, nrev = _run_settings(st, function, base_cfg)
    variables = _parse_variables(raw.get("vary", {}), function, base, sampler, FUNCTIONS)
    speeds = _parse_speeds(st.get("speeds"), function, variables)
    names = list(FUNCTIONS[function].outputs) if function else list(OUTPUTS) + list(GAS_OUTPUTS)
    outputs, limits, constraints, objective = _outputs_and_limits(raw, st, names, base, base_cfg)
    booster_pressure = None
    if function is None:
        asked = list(dict.fromkeys(list(outputs) + list(limits) + list(constraints) + objective))
        _check_tip_pv(asked, base)
        booster_pressure = check_gas_outputs(asked, base_cfg, speeds, model, st.get("booster_pressure"))
    opt = raw.get("optimize", {})
    sens = raw.get("sensitivity", {})
    for tbl, where in ((opt, "optimize"), (sens, "sensitivity")):
        if not isinstance(tbl, dict):
            raise ConfigError(f"[{where}] must be a table")
    scheduler, workers, batch = _parse_execution(st)
    warnings = [w for v in variables for w in plausibility_warnings(base, v)] if function is None else []
    return Study(path=path, base=base, config_path=None if cfg_path is None else str(cfg_path),
                 variables=variables, sampler=sampler, samples=samples, seed=seed, speeds=speeds,
                 outputs=outputs, model=model, revolution_samples=nrev, limits=limits,
                 objective=objective, constraints=constraints, optimize=opt, sensitivity=sens,
                 scheduler=scheduler, workers=workers, batch_size=batch, function=function, raw=raw,
                 revolutions=revolutions, warnings=warnings, booster_pressure=booster_pressure)


def _available(names: list, base: dict, base_cfg) -> list:
    """The outputs a study reports when study.outputs is omitted: those this config can give."""
    if base_cfg is None:
        return names
    return [o for o in names if not (o == "max_tip_pv" and get_value(base, "rotor.width") is None)
            and not (o in GAS_OUTPUTS and (base_cfg.pneumatic is None or (
                o == "mean_current" and not base_cfg.pneumatic.motor)))]


def _check_tip_pv(asked: list, base: dict) -> None:
    if "max_tip_pv" in asked and get_value(base, "rotor.width") is None:
        raise ConfigError("max_tip_pv (contact pressure x slip speed) needs the contact area: give "
                          "rotor.width (the axial width of rotor and vanes) in the config")


def _study_table(raw: dict) -> dict:
    """The [study] table, after checking the top-level tables' and its own keys."""
    for k in raw:
        if k not in _TOP_KEYS:
            raise ConfigError(f"unknown study table '{k}' (one of {', '.join(sorted(_TOP_KEYS))})")
    st = raw.get("study", {})
    if not isinstance(st, dict):
        raise ConfigError("[study] must be a table")
    for k in st:
        if k not in _STUDY_KEYS:
            raise ConfigError(f"unknown key 'study.{k}'")
    return st


def _base_config(st: dict, function, base_dir, functions) -> tuple:
    """(raw base config, its path, the checked PumpConfig); ({}, None, None) for an analytic function."""
    if function is not None:
        if function not in functions:
            raise ConfigError(f"study.function must be one of {', '.join(functions)}, got {function!r}")
        if "config" in st:
            raise ConfigError("give study.config or study.function, not both")
        return {}, None, None
    if "config" not in st:
        raise ConfigError("missing required key 'study.config' (the base pump config)")
    cfg_path = Path(base_dir) / st["config"]
    base = _read_toml(cfg_path, "study.config")
    try:
        base_cfg = config_from_dict(base, name_default=cfg_path.stem)
    except ConfigError as e:
        raise ConfigError(f"study.config '{cfg_path}': {e}") from None
    from ..geometry import check_geometry

    try:
        check_geometry(base_cfg)
    except ConfigError as e:
        raise ConfigError(f"study.config '{cfg_path}': {e}") from None
    return base, cfg_path, base_cfg


def _parse_variables(vary, function, base: dict, sampler: str, functions) -> list:
    """The [vary."KEY"] tables as Variables, each checked against the function's inputs or the config."""
    if not isinstance(vary, dict) or not vary:
        raise ConfigError("the study needs at least one [vary.\"KEY\"] table")
    variables = []
    for key, spec in vary.items():
        if function is not None:
            if key not in functions[function].inputs:
                raise ConfigError(f"vary.\"{key}\": {function} takes {', '.join(functions[function].inputs)}")
            default = None
        else:
            if not config_key_ok(key):
                raise ConfigError(f"vary.\"{key}\" is not a numeric config key path (e.g. housing.radius, "
                                  "vane.mass, friction.housing.dynamic, housing.center.0)")
            default = base_value(base, key)
        var = parse_variable(key, spec, default, sampler)
        if schema_leaf(key) == "int" and (var.values is None or any(x != int(x) for x in var.values)):
            raise ConfigError(f"vary.\"{key}\" is an integer key: give integer values")
        if function is None:
            at = var.values[0] if var.values else (default if default is not None else var.bounds[0])
            if not key_targets(base, key, at):
                raise ConfigError(f"vary.\"{key}\" does not enter the constrained or gas model's "
                                  "parameters (model_spec registry) or the speed; it cannot change an output")
        variables.append(var)
    if sampler == "grid":
        grid_bad = [v.key for v in variables if v.values is None]
        if grid_bad:
            raise ConfigError(f"study.sampler = \"grid\" needs values or range for every key; "
                              f"vary.\"{grid_bad[0]}\" has a distribution")
    return variables


def _parse_speeds(speeds, function, variables) -> list | None:
    """study.speeds as floats (a pump study only, not together with a varied speed); None if not given."""
    if speeds is None:
        return None
    if function is not None:
        raise ConfigError("study.speeds is for a pump study")
    if not isinstance(speeds, list) or not speeds or not all(_num(x) and x > 0 for x in speeds):
        raise ConfigError(f"study.speeds must be a list of speeds > 0 [rad/s], got {speeds!r}")
    if SPEED_KEY in [v.key for v in variables]:
        raise ConfigError(f"give study.speeds or vary.\"{SPEED_KEY}\", not both")
    return [float(x) for x in speeds]


def _check_numeric_output(o: str, where: str, names: list) -> None:
    """o must name a numeric output (limits, constraints and objectives take no flags)."""
    if o not in names and not (o.startswith("friction_power_") and o[15:].isdigit()):
        raise ConfigError(f"{where}: unknown output {o!r} (one of {', '.join(names)})")
    if o in BOOL_OUTPUTS:
        raise ConfigError(f"{where}: {o} is a flag; limits and objectives take numeric outputs")


def _parse_objective(obj, names: list) -> list:
    """[objective] minimize = OUTPUT or a list of them (a Pareto front); [] without the table."""
    objective = []
    if obj:
        if not isinstance(obj, dict) or set(obj) - {"minimize"}:
            raise ConfigError("[objective] takes minimize = OUTPUT (or a list of outputs for a Pareto front)")
        objective = obj.get("minimize")
        objective = [objective] if isinstance(objective, str) else objective
        if not isinstance(objective, list) or not objective or not all(isinstance(o, str) for o in objective):
            raise ConfigError("objective.minimize must be an output name or a list of them")
        for o in objective:
            _check_numeric_output(o, "objective.minimize", names)
    return objective


def _parse_execution(st: dict) -> tuple:
    """(scheduler address, workers, batch size) from [study], each None when not given."""
    scheduler = st.get("scheduler")
    if scheduler is not None and not isinstance(scheduler, str):
        raise ConfigError(f"study.scheduler must be an address string, got {scheduler!r}")
    workers = st.get("workers")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"study.workers must be an integer >= 1, got {workers!r}")
    batch = st.get("batch_size")
    if batch is not None and (not isinstance(batch, int) or batch < 1):
        raise ConfigError(f"study.batch_size must be an integer >= 1, got {batch!r}")
    return scheduler, workers, batch


__all__ = ["Study", "load_study", "study_from_dict", "apply_values", "DISTRIBUTIONS", "Variable"]
