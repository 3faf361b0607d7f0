"""The Python API behind `pumpsim.identify` and `pumpsim.diagnose`: the same inputs, defaults and
checks as the command line, for a config given as a path or a `PumpConfig` and data given as a
path, a `Dataset`, arrays, or a list of those (several measurements fitted together) -- or a bench
log (a `BenchLog`, or a file with the columns time, voltage, current, booster_pressure), which
both recognise as the command line does."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .blas import small_solves
from .checks import PumpConfig, checked_config
from .data import DataOptions, Dataset, load_data
from .errors import ConfigError, DataError


def as_config(config, force: bool = False) -> PumpConfig:
    """A `PumpConfig` from a config object or a TOML path."""
    if isinstance(config, PumpConfig):
        return config
    if isinstance(config, (str, Path)):
        return checked_config(config, force=force)
    raise ConfigError(f"config must be a PumpConfig or a path to a TOML file, got {type(config).__name__}")


def _arrays(d, source) -> Dataset:
    """A Dataset from {"time", "torque"[, "speed", "angle"]} arrays or a (time, torque[, speed]) tuple."""
    if isinstance(d, dict):
        unknown = set(d) - {"time", "torque", "speed", "angle"}
        if unknown or not {"time", "torque"} <= set(d):
            raise DataError(f"{source}: data arrays need the keys time and torque (optional speed, angle), "
                            f"got {', '.join(sorted(d))}")
        cols = dict(d)
    else:
        if not 2 <= len(d) <= 3:
            raise DataError(f"{source}: give (time, torque) or (time, torque, speed) arrays")
        cols = dict(zip(("time", "torque", "speed"), d))
    arr = {}
    for k, v in cols.items():
        if v is None:
            continue
        try:
            a = np.asarray(v, dtype=float).ravel()
        except (TypeError, ValueError):
            raise DataError(f"{source}: {k} is not an array of numbers") from None
        arr[k] = a
    n = arr["time"].size
    for k, a in arr.items():
        if a.size != n:
            raise DataError(f"{source}: {k} has {a.size} samples, time has {n}")
        bad = np.nonzero(~np.isfinite(a))[0]
        if bad.size:
            raise DataError(f"{source}: sample {bad[0]} of {k} is not a finite number")
    if n < 10:
        raise DataError(f"{source}: {n} samples; at least 10 are needed")
    bad = np.nonzero(np.diff(arr["time"]) <= 0)[0]
    if bad.size:
        raise DataError(f"{source}: time must be strictly increasing (sample {bad[0] + 1})")
    return Dataset(arr["time"], arr["torque"], arr.get("speed"), arr.get("angle"), source=source)


def as_datasets(data, options: DataOptions | None = None, nominal_speed=None) -> list[Dataset]:
    """A list of Datasets from a path, a Dataset, arrays (dict or tuple) or a list of those."""
    items = data if isinstance(data, list) else [data]
    if not items:
        raise DataError("no data given")
    out = []
    for i, d in enumerate(items):
        if isinstance(d, Dataset):
            out.append(d)
        elif isinstance(d, (str, Path)):
            out.append(load_data(d, options, nominal_speed=nominal_speed))
        elif isinstance(d, (dict, tuple)):
            out.append(_arrays(d, f"data arrays #{i}" if len(items) > 1 else "data arrays"))
        else:
            raise DataError(f"data must be a path, a Dataset, arrays or a list of them, got {type(d).__name__}")
    return out


def bench_log(config: PumpConfig, data, options: DataOptions | None = None):
    """The bench log `data` is (a BenchLog, or a file with a bench log's columns, read with
    `options` and checked against `config`), or None for torque data."""
    from .benchlog import BenchLog, is_bench_log, read_bench_log

    if isinstance(data, BenchLog):
        return data
    if isinstance(data, (str, Path)) and is_bench_log(data, options):
        return read_bench_log(data, config, options)
    return None


@small_solves
def identify(config, data, params=None, *, method="gauss-newton", relaxation=1.0,
             initial=None, max_iter=50, options: DataOptions | None = None, force=False, log=None):
    """Fit model parameters to measured drive torque at constant speed.

    Parameters
    ----------
    config : PumpConfig or path
        The pump (TOML, SI units: m, kg, s, rad, N).
    data : path, Dataset, {"time", "torque"[, "speed", "angle"]} arrays, (time, torque[, speed]), or a list
        Time [s], torque [N m], speed [rad/s], angle [rad]. Files: CSV (units from the header, e.g.
        `torque [N*mm]`), MATLAB .mat, NI .tdms. A list is fitted jointly (one pump, several speeds).
    params : sequence of str, default ("mu", "theta0") as the command line (for a bench log: "mu",
        "booster.leak", "motor.resistance", or any numeric config key path of the pump-down model)
        mu (vane-housing dynamic COF, slot COF tied to it in the configured proportion), mu_slot,
        theta0 [rad], speed [rad/s], torque_offset [N m], delay [s], or a numeric config key path
        (e.g. "housing.center.0").
    method : "gauss-newton" (default), "levenberg-marquardt" or "ipopt"
    relaxation : Gauss-Newton relaxation factor in (0, 1]
    initial : {name: start value}
    max_iter : iteration limit
    options : DataOptions for reading files (column names, units, resampling)
    force : proceed although the unit checks suspect a unit mistake (else DataError / ConfigError)
    log : callable(history entry) after every iteration

    Returns
    -------
    IdentificationResult: `.estimates` (value, stderr, 95 % interval per name), `.rms` [N m],
    `.converged`, `.problems()` (not converged / on a bound / not identifiable: empty when usable),
    `.to_json()`; `print(result)` shows the table.

    Example::

        import pumpsim
        res = pumpsim.identify("examples/test_rig.toml", "examples/data/test_rig_measurement.csv")
        print(res.value("mu"), res.estimates["mu"].stderr)
    """
    from .identification import identify as _identify
    from .identification.speed_note import speed_notes
    from .plausibility import check_measurement

    cfg = as_config(config, force)
    params = [params] if isinstance(params, str) else (None if params is None else list(params))
    log_data = bench_log(cfg, data, options)
    if log_data is not None:
        from .identification.pumpdown_fit import fitting, identify_bench

        with fitting(params):
            return identify_bench(cfg, log_data, *([params] if params else []), method=method, initial=initial,
                                  max_iter=max_iter, relaxation=relaxation, progress=log)
    params = params or ["mu", "theta0"]
    nominal = None if "speed" in params or cfg.mode != "speed" else cfg.speed
    datasets = as_datasets(data, options, nominal)
    warnings = list(cfg.warnings)
    for d in datasets:
        warnings += check_measurement(cfg, d, params, force=force)
    res = _identify(cfg, datasets if len(datasets) > 1 else datasets[0], params=params, method=method,
                    relaxation=relaxation, initial=initial, max_iter=max_iter, log=log)
    res.warnings = warnings
    res.notes += speed_notes(cfg, datasets, res)  # here, not in the fit engine: diagnose's fits need none
    return res


@small_solves
def diagnose(config, data, *, options: DataOptions | None = None, force=False, progress=None,
             speed_tolerance=None, budget=None):
    """The discrepancy workflow: fit the baseline (mu, theta0 and the speed when the data has none),
    test the residual, then name and add the effects the model lacks (the discrepancy workflow
    of the documentation's explanation section).

    Parameters
    ----------
    config : PumpConfig or path (TOML, SI units)
    data : path, Dataset, arrays (as for `identify`) or a list of them: several measurements of one
        pump (different speeds separate offset, viscous friction and COF)
    options : DataOptions for reading files
    force : proceed although the unit checks suspect a unit mistake
    progress : callable(message) for progress lines
    speed_tolerance : relative band about the configured speed for data without a speed column
        (default: operation.speed_tolerance, 0.02)
    budget : wall seconds after which no further search step starts (None: no limit); what it cut
        is listed in `d["budget"]` and the notes

    A bench log is diagnosed with the pump-level library (booster leak, tip clearance, late exhaust
    valve, motor friction, supply resistance, winding heating, and the bench's current and pressure
    sensors' calibration) and returns a BenchDiagnosis (`.to_json()`, `.summary()`);
    `pumpsim.diagnosis.pump_workflow.diagnose_bench` takes its options (resistance_known,
    atmosphere_known).

    Returns
    -------
    DiagnosisResult: `d["key"]` reads the JSON output (baseline, steps, effects, final, verdict,
    unexplained, confounded, notes, ...), `d.to_json()` is all of it; `d.steps`, `d.screens` and
    `d.history` (the fit behind each model: `d.history[0].result` is the baseline's) are typed;
    `print(d)` shows the step table.

    Example::

        import pumpsim
        d = pumpsim.diagnose("examples/ellipse_4vanes.toml", "examples/data/ellipse_hidden_effects.csv")
        print(d["effects"])
    """
    from .diagnosis import diagnose as _diagnose
    from .plausibility import check_measurement

    cfg = as_config(config, force)
    log_data = bench_log(cfg, data, options)
    if log_data is not None:
        from .diagnosis.pump_workflow import diagnose_bench

        return diagnose_bench(cfg, log_data, progress=progress, budget=budget)
    datasets = as_datasets(data, options, cfg.speed if cfg.mode == "speed" else None)
    warnings = list(cfg.warnings)
    for d in datasets:
        if d.measured is not None and not np.all(d.measured):
            # its spectra and screens read the residual as one uniform record: no sample can be left out
            raise DataError(f"data '{d.name}': {int(np.sum(~d.measured))} resampled samples lie inside a gap "
                            "in time (interpolated, not measured) and the diagnosis needs one continuous "
                            "record; cut the record at the gap and diagnose each part")
        warnings += check_measurement(cfg, d, ("mu", "theta0"), force=force)
    for w in warnings:  # accepted under force: say so where the user looks
        if progress:
            progress(f"warning: {w}")
    return _diagnose(cfg, datasets, progress=progress, speed_tolerance=speed_tolerance, budget=budget)
