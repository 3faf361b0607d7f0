"""A study's designs as parameter vectors: NumPy over all designs at once, no config per design.

A `DesignMap` is made once per study and compiled variant: the base design's validated config
(with the variant's structural key values, e.g. rotor.vanes), and for every varied key the
entries of the kernel's parameter vector it sets (itself, a housing shape key's semi-axes times
their factor, a section's fallback copy) and the derived defaults that follow it (vane.inertia
from vane.mass). `vectors(X)` maps the designs' key values to their parameter vectors and checks
the registry bounds of the entries that move, as the config's validation does, one NumPy
comparison per entry over every design. A design any check rejects is left to the per-design
path (`evaluate.prepare`), which gives its reason in the config's own words; so does every design
of a study whose keys this map does not cover (an integer key other than rotor.vanes, the
rotor width, lists, the gas tables, the contact model, a motor).

The map is checked against the config path once per call (the first admitted design's vector
must equal the one `config_from_dict` gives, bit for bit): a key whose effect it misreads sends
the whole call to the per-design path instead of computing other numbers.
"""
from __future__ import annotations

import math

import numpy as np

from ..config import RPM, as_array, config_from_dict, shape_key_parameter
from ..errors import ConfigError
from ..model_spec import housings
from ..model_spec.parameters import DERIVED, SECTION_FALLBACK, Structure, derive, layout, layout_names
from .study import SPEED_KEY, get_value, key_targets

STRUCTURE_KEYS = ("rotor.vanes",)
SPEED_KEYS = {SPEED_KEY: 1.0, "operation.speed_rpm": RPM}


def covered(study) -> bool:
    """Whether the study's designs can go through DesignMap (the constrained model, no gas
    outputs, no analytic function)."""
    return study.function is None and study.model == "constrained" and study.booster_pressure is None


class DesignMap:
    """The varied keys' effect on the parameter vector of one compiled variant (see the module)."""

    def __init__(self, study, fixed: dict):
        self.study = study
        self.table = study.design_dict(fixed)
        self.cfg = config_from_dict(self.table)  # a ConfigError: the caller's per-design path
        if self.cfg.pneumatic is not None or self.cfg.mode != "speed":
            raise ConfigError("the gas tables or a torque/motor drive: per design")
        self.structure = self.cfg.structure_for("constrained")
        self.names = layout_names(self.structure)
        self.index = {nm: i for i, nm in enumerate(self.names)}
        self.p0 = as_array(self.cfg.parameters("constrained"))
        self.keys = [k for k in study.keys if k not in STRUCTURE_KEYS]
        self.sets = {k: self._targets(k) for k in self.keys if k not in SPEED_KEYS}
        self.moved = {t for ts in self.sets.values() for t, _ in ts}
        self.derived = []
        for q in DERIVED:  # in fill_derived's order: a default may follow another
            if q.name not in self.cfg.given and set(q.inputs) & self.moved:
                self.derived.append(q)
                self.moved.add(q.name)
        shape = housings.SHAPES[self.cfg.shape]
        self.shape_keys = [k for k in shape.keys if k.path in self.keys]
        if self.shape_keys and self.cfg.harmonics:
            raise ConfigError("housing harmonics with a varied housing size: per design")
        self.checks = self._checks()

    def _targets(self, key) -> list:
        """[(parameter entry, factor)] a key sets (entry = factor x value)."""
        base = get_value(self.table, key)
        entries = [t for t in key_targets(self.table, key, base) if not self._derived(t)]
        out = []
        shape = housings.SHAPES[self.cfg.shape]
        for t in entries:
            found = shape.key_setting(t)
            if found is not None and found[0].path == key:
                out.append((t, found[1]))
            elif t == key or SECTION_FALLBACK.get(t.rsplit(".", 1)[0]) == key.rsplit(".", 1)[0]:
                out.append((t, 1.0))
            else:
                raise ConfigError(f"vary.\"{key}\" moves {t}: per design")
            if t not in self.index:
                raise ConfigError(f"vary.\"{key}\" moves {t}, not a kernel parameter: per design")
        return out

    def _derived(self, name) -> bool:
        return any(q.name == name for q in DERIVED) and name not in self.cfg.given

    def _checks(self) -> list:
        """(entry as the config names it, parameter, factor) of every registry bound a moving
        entry may break (its own bounds, or bounds that name a moving entry)."""
        shape = housings.SHAPES[self.cfg.shape]
        out = []
        for q in layout(Structure("contact", 1, 0)):
            if q.name not in self.cfg.values:
                continue
            refs = {q.name, q.below} | {b.value for b in (q.lower, q.upper) if isinstance(b.value, str)}
            if not refs & self.moved:
                continue
            found = shape.key_setting(q.name)
            if found is None:
                out.append((q, q.name, 1.0))
            elif found[0].sets[0][0] == q.name:  # a key setting several entries is checked once
                out.append((shape_key_parameter(found[0]), q.name, found[1]))
        return out

    def vectors(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(P (designs, parameters), speed (designs,), admitted (designs,) bool) for key values X
        (designs, study.keys). A design not admitted goes the per-design way."""
        D = len(X)
        col = {k: X[:, self.study.keys.index(k)] for k in self.keys}
        ok = np.all(np.isfinite(X), axis=1) if X.size else np.ones(D, bool)
        P = np.repeat(self.p0[None, :], D, axis=0)
        vals = {**self.cfg.values, **{nm: P[:, i] for nm, i in self.index.items()}}
        for k, ts in self.sets.items():
            for t, factor in ts:
                P[:, self.index[t]] = factor * col[k]
        for q in self.derived:  # as fill_derived: object arrays keep Python's float arithmetic
            env = {nm: vals[nm].astype(object) for nm in q.inputs}
            P[:, self.index[q.name]] = np.asarray(derive(q.derived, env), dtype=float)
        speed = np.full(D, float(self.cfg.speed))
        for k, unit in SPEED_KEYS.items():
            if k in col:
                speed = col[k] * unit
                ok &= speed > 0
        for q, name, factor in self.checks:
            ok &= _within(q, vals, name, factor)
        ok &= self._shape_ok(col, D)
        return P, speed, ok

    def _shape_ok(self, col, D) -> np.ndarray:
        """The housing shape's own check (a varied size: per design; a few Python operations)."""
        shape = housings.SHAPES[self.cfg.shape]
        ok = np.ones(D, bool)
        if self.shape_keys and shape.check is not None:
            given = {k.name: get_value(self.table, k.path) for k in shape.keys}
            for d in range(D):
                ok[d] = not shape.check({**given, **{k.name: float(col[k.path][d]) for k in self.shape_keys}})
        return ok

    def agrees(self, P_row, speed, values: dict) -> bool:
        """Whether the config path gives this design the same vector and speed, bit for bit."""
        try:
            cfg = config_from_dict(self.study.design_dict(values))
        except ConfigError:
            return False
        p = as_array(cfg.parameters("constrained"))
        return (cfg.structure_for("constrained") == self.structure and np.array_equal(p, P_row)
                and float(cfg.speed) == float(speed) and cfg.angle == self.cfg.angle)


def _within(q, vals, name, factor) -> np.ndarray:
    """Parameter.check over designs: its value (a shape key's: the entry / factor) within its
    bounds and below its `below` entry."""
    v = vals[name] / factor if factor != 1.0 else vals[name]
    env = {**vals, q.name: v}
    lo, hi = q.lower.at(env), q.upper.at(env)
    ok = (v > lo if q.lower.open else v >= lo) & (v < hi if q.upper.open else v <= hi)
    if q.below:
        ok &= v < env[q.below]
    return np.asarray(ok, dtype=bool)


_CACHE: dict = {}  # (study hash, structural values) -> DesignMap or its ConfigError: a study's tasks share it


def design_map(study, fixed: dict) -> DesignMap:
    key = (study.study_hash(), tuple(sorted(fixed.items())))
    if key not in _CACHE:
        if len(_CACHE) > 64:
            _CACHE.clear()
        try:
            _CACHE[key] = DesignMap(study, fixed)
        except ConfigError as e:
            _CACHE[key] = e
    if isinstance(_CACHE[key], ConfigError):
        raise _CACHE[key]
    return _CACHE[key]


def design_maps(study, X) -> tuple[list, np.ndarray]:
    """([(DesignMap, rows of X)] per structural value set, rows left to the per-design path)."""
    if not covered(study) or not len(X):
        return [], np.arange(len(X))
    skeys = [k for k in study.keys if k in STRUCTURE_KEYS]
    if skeys:
        S = X[:, [study.keys.index(k) for k in skeys]]
        if not np.all(np.isfinite(S)):
            return [], np.arange(len(X))
        groups = {}
        for j, row in enumerate(map(tuple, S.tolist())):
            groups.setdefault(row, []).append(j)
    else:
        groups = {(): list(range(len(X)))}
    maps, rest = [], []
    for row, members in groups.items():
        try:
            maps.append((design_map(study, {k: int(round(x)) for k, x in zip(skeys, row)}), np.array(members)))
        except ConfigError:
            rest += members
    return maps, np.array(sorted(rest), dtype=int)


def mouth_depths(names_index, P) -> np.ndarray:
    """geometry.mouth_depth per design, bit for bit: the slot tilt's cosine and sine by `math` (as
    it takes them) once per distinct tilt, the rest correctly rounded operations in NumPy."""
    rb, beta, Rr = (P[:, names_index[k]] for k in ("rotor.slot_radius", "rotor.slot_tilt", "rotor.radius"))
    cb, sb = np.full(len(P), math.nan), np.full(len(P), math.nan)
    for b in np.unique(beta):
        at = beta == b
        cb[at], sb[at] = math.cos(b), math.sin(b)
    return -rb * cb + np.sqrt(Rr * Rr - rb * rb * (sb * sb))


__all__ = ["DesignMap", "design_maps", "covered", "mouth_depths"]
