"""The Solution of a simulation, either model: named columns (spec §7), every kernel output by name
(computed on first use and cached), the parameters and kernel key used, solver statistics, events
and warnings (reported in one place), CSV, Parquet and plots."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .io import atomic_path
from .model_spec.simd import SUBSETS
from .tolerances import LIFT_OFF_ROUNDING_REL, PARADOX_TOL

PER_VANE_COLUMNS = ("s", "sdot", "normal", "slot1", "slot2")
# what every simulation evaluates up front: the spec columns and what the warnings read (the
# SIMD library has an entry point for exactly these)
REPORTED = SUBSETS["reported"]
assert REPORTED[:len(PER_VANE_COLUMNS)] == PER_VANE_COLUMNS


def contact_warnings(out, time, warnings, events=None, lift_off=False) -> None:
    """Report, never hide: would-be lift-off (Model 2: a negative housing reaction) and friction
    paradoxes (no or several consistent slot contact-side sets), for both models, as warnings
    and (when `events` is a list) events."""
    n_vanes = out["normal"].shape[0]
    kinds = []
    if lift_off:  # a reaction of -1e-15 N at rest is rounding, not a lift-off
        kinds.append(("lift_off", out["normal"] < -LIFT_OFF_ROUNDING_REL * np.max(np.abs(out["normal"]))))
    paradox = out["n_consistent"] < 0.5
    if "ambiguity" in out:  # the gas Model 2 kernel exports the consistent-set count only
        paradox = paradox | (out["ambiguity"] > PARADOX_TOL)
    kinds.append(("friction_paradox", paradox))
    for kind, bad in kinds:
        for i in range(n_vanes):
            if not bad[i].any():
                continue
            k = int(np.argmax(bad[i]))
            if kind == "lift_off":
                msg = (f"vane {i} would lift off: housing reaction {out['normal'][i, k]:.4g} N < 0 at "
                       f"t = {time[k]:.6g} s ({int(bad[i].sum())} samples); Model 2 assumes contact, "
                       "use model='contact'")
            else:
                what = ("no consistent contact-side set" if out["n_consistent"][i, k] < 0.5 else
                        f"{int(out['n_consistent'][i, k])} consistent contact-side sets")
                msg = (f"friction paradox at vane {i}, t = {time[k]:.6g} s: {what} for the slot-wall "
                       f"forces ({int(bad[i].sum())} samples); the least inconsistent set is reported")
            warnings.append(msg)
            if events is not None:
                events.append({"time": float(time[k]), "kind": kind, "vane": i, "message": msg})


class LazyOutputs(dict):
    """Kernel outputs by name, evaluated on first use (one kernel call over the trajectory) and
    cached; `evaluate(names) -> {name: array}`, `names` those it can compute."""

    def __init__(self, ready=None, evaluate=None, names=()):
        super().__init__(ready or {})
        self._evaluate, self._names = evaluate, tuple(names)

    def __missing__(self, name):
        if self._evaluate is None or name not in self._names:
            raise KeyError(f"no output '{name}'; available: {', '.join(self.available())}")
        self[name] = self._evaluate([name])[name]
        return self[name]

    def available(self) -> list:
        return sorted(set(self) | set(self._names))


@dataclass
class Solution:
    model: str
    mode: str
    time: np.ndarray
    angle: np.ndarray
    speed: np.ndarray
    torque: np.ndarray
    vanes: dict  # spec §7 per-vane column name -> array (n_vanes, n_samples)
    parameters: dict
    stats: dict = field(default_factory=dict)
    events: list = field(default_factory=list)  # dicts: time, kind, vane, message
    warnings: list = field(default_factory=list)
    termination: str = "completed"
    # every other kernel output by name ((n_vanes, n) or (n,)), computed on first use, and
    # solver traces (contact model: step size)
    extra: dict = field(default_factory=LazyOutputs)
    kernel_key: str = ""  # the compiled library's content key (model_spec.manifest)
    config_name: str = ""  # the config's `name`: figure titles say which pump this is
    _columns: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        if not isinstance(self.extra, LazyOutputs):
            self.extra = LazyOutputs(self.extra)

    @property
    def n_vanes(self) -> int:
        return self.vanes["s"].shape[0]

    def per_vane_columns(self):
        cols = list(PER_VANE_COLUMNS)
        if "penetration" in self.vanes:
            cols.append("penetration")
        return cols

    def column_names(self) -> list:
        names = ["time", "angle", "speed", "torque"]
        return names + [f"{c}_{i}" for i in range(self.n_vanes) for c in self.per_vane_columns()]

    def columns(self) -> dict:
        """The spec §7 columns by name (SI units): time, angle, speed, torque, s_i, sdot_i, normal_i,
        slot1_i, slot2_i (and penetration_i for the contact model).

        Example::

            res = pumpsim.simulate(pumpsim.load_config("examples/test_rig.toml"))
            list(res.columns())[:4]     # ['time', 'angle', 'speed', 'torque']
        """
        return {name: self[name] for name in self.column_names()}

    def __repr__(self):
        return (f"<{type(self).__name__} {self.model} model, {self.mode} drive, {self.n_vanes} vane(s), "
                f"{len(self.time)} samples over {self.time[-1] - self.time[0]:.4g} s ({self.termination})>")

    def __str__(self):
        return self.summary()

    def __getitem__(self, name):
        """A spec §7 column ('torque', 's_0', ...), or any kernel output by name (per vane: an
        (n_vanes, n) array; 'kinetic_energy_2' for one vane), cached."""
        if name not in self._columns:
            self._columns[name] = self._column(name)
        return self._columns[name]

    def _column(self, name):
        if name in ("time", "angle", "speed", "torque"):
            return getattr(self, name)
        base, _, index = name.rpartition("_")
        source = self.vanes if base in self.vanes else self.extra
        if index.isdigit() and (base in self.vanes or base in self.extra.available()):
            return source[base][int(index)]
        try:
            return self.extra[name]
        except KeyError:
            raise KeyError(f"no column or output '{name}'; columns: {', '.join(self.column_names()[:8])}, "
                           f"...; outputs: {', '.join(self.extra.available())}") from None

    def to_csv(self, path) -> None:
        """Write the spec §7 columns (time [s], angle [rad], speed [rad/s], torque [N m], per vane
        s_i [m], sdot_i [m/s], normal_i, slot1_i, slot2_i [N]) as CSV, atomically.

        Example::

            res = pumpsim.simulate(pumpsim.load_config("examples/test_rig.toml"))
            res.to_csv("out.csv")
        """
        cols = self.columns()
        data = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
        with atomic_path(path) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")

    def to_parquet(self, path) -> None:
        """The spec §7 columns as a Parquet file (needs pyarrow: pip install pyarrow)."""
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            from .errors import ConfigError

            raise ConfigError(f"writing '{path}' needs pyarrow, which is not installed "
                              "(pip install pyarrow; or write CSV)") from None
        cols = self.columns()
        table = pa.table({k: np.asarray(v, dtype=float) for k, v in cols.items()},
                         metadata={"kernel_key": self.kernel_key, "model": self.model})
        with atomic_path(path) as tmp:
            pq.write_table(table, tmp)

    def plot(self, path, name: str | None = None, x: str = "angle") -> None:
        """Write the figure set (.png/.svg/.pdf) to `path`: versus rotor angle in degrees,
        revolutions overlaid (x="time": versus time); `name` (the config's) goes into the title.

        Example::

            res = pumpsim.simulate(pumpsim.load_config("examples/test_rig.toml"))
            res.plot("out.png")
        """
        from .report.simulation import plot_simulation

        plot_simulation(self, path, name=name, x=x)

    def summary(self, warnings: bool = True) -> str:
        """A few lines for a terminal: model, drive, samples, torque and normal-force ranges [N m, N],
        solver statistics and (unless warnings=False: the command line prints them on stderr) the
        warnings.

        Example::

            print(pumpsim.simulate(pumpsim.load_config("examples/test_rig.toml")).summary())
        """
        tq = self.torque
        lines = [
            f"model {self.model}, {self.mode} drive, {self.n_vanes} vane(s), "
            f"{self.time[-1] - self.time[0]:.4g} s, {len(self.time)} samples ({self.termination})",
            f"torque: mean {tq.mean():.6g} N m, min {tq.min():.6g}, max {tq.max():.6g}",
            f"speed: mean {self.speed.mean():.6g} rad/s",
            f"housing normal force: max {self.vanes['normal'].max():.4g} N, "
            f"min {self.vanes['normal'].min():.4g} N",
        ]
        if self.stats:
            lines.append("solver: " + ", ".join(f"{k} {v:g}" if isinstance(v, (int, float)) else f"{k} {v}"
                                                  for k, v in self.stats.items()))
        lines += [f"warning: {w}" for w in self.warnings] if warnings else []
        return "\n".join(lines)


SimulationResult = Solution  # the name the API has used
