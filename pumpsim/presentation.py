"""How numbers are shown to an engineer: parameter names and units, the meaning of "±", value
formatting and the provenance of a result. One place, so the CLI text and the HTML reports agree.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import math
import re
import shlex
import sys
from pathlib import Path

import numpy as np

# "±" means the same on the terminal, in JSON ("stderr") and in the HTML reports.
PLUS_MINUS = ("± = one standard error (1σ, from σ²(JᵀJ)⁻¹, or the residual-aware Newey-West one where an "
              "intervals note says so); 95 % intervals use the t distribution")

OPTIMISTIC = ("the residual is not white: the ± and the intervals assume independent errors and are "
              "optimistic (too narrow)")

# fitted names that are not config keys (identification: Problem.SPECIAL): label, SI unit
_SPECIAL = {
    "mu": ("vane–housing COF μ (dynamic)", "-"),
    "booster.pressure": ("booster pressure at the log's first sample (fitted with the log)", "Pa"),
    "mu_slot": ("slot-wall COF μ_r (dynamic)", "-"),
    "theta0": ("rotor angle at the first sample θ0", "rad"),
    "speed": ("rotor speed ω", "rad/s"),
    "speed0": ("initial rotor speed ω0", "rad/s"),
    "torque_offset": ("torque-sensor offset", "N m"),
    "delay": ("time delay of the torque signal", "s"),
    "lag": ("torque-sensor time constant", "s"),
    "ripple_cos": ("speed ripple, cos component (relative)", "-"),
    "ripple_sin": ("speed ripple, sin component (relative)", "-"),
    "sensor.current_gain": ("current sensor's gain (1: calibrated)", "-"),
    "sensor.pressure_gain": ("pressure sensor's span (1: calibrated)", "-"),
    "sensor.pressure_offset": ("pressure sensor's offset (0: calibrated)", "Pa"),
}
_CONFIG_DOC = {
    "housing.center.0": "housing centre x (rotor eccentricity)",
    "housing.center.1": "housing centre y (rotor eccentricity)",
    "housing.a": "housing semi-axis a", "housing.b": "housing semi-axis b",
    "housing.angle": "housing angle ψ",
    "effects.viscous_tip_friction": "viscous tip friction (force per slip speed)",
    "operation.bearing_torque": "bearing torque",
    "leak.tip_gap": "vane-tip clearance (leak gap)",
    "leak.end_gap": "end-face clearance (leak gap)",
    "motor.resistance": "motor winding resistance",
    "valve.cracking": "exhaust valve cracking pressure difference",
    "booster.leak": "booster leak (mass flow at full atmospheric difference)",
    "motor.constant": "motor torque and back-EMF constant k",
    "motor.friction": "motor friction torque",
}
UNIT_TEXT = {"-": "–", "N m": "N·m", "kg m^2": "kg·m²", "N s/m": "N·s/m", "rad": "rad", "m": "m", "ohm": "Ω",
             "N m/A": "N·m/A"}


def _registry_entry(name: str):
    from .model_spec.parameters import GAS_PARAMETERS, Structure, layout

    generic = re.sub(r"^(housing\.harmonics|effects\.vane_friction_factor)\.\d+", r"\1.0", name)
    found = {p.name: p for p in layout(Structure(model="contact", vanes=1, harmonics=1))}.get(generic)
    return found or {q.name: q for q in GAS_PARAMETERS}.get(name)


def _registry_unit(name: str) -> str | None:
    q = _registry_entry(name)
    return None if q is None else q.unit


def split_measurement(name: str):
    """'theta0@1' -> ('theta0', 1); 'mu' -> ('mu', None): joint fits name per-measurement values."""
    base, sep, idx = name.partition("@")
    return base, (int(idx) if sep and idx.isdigit() else None)


def describe(name: str, harmonics=None) -> tuple[str, str]:
    """(label an engineer reads, SI unit) for a fitted parameter name. `harmonics`: the config's
    list of [k, A, γ] so a harmonic slot is named by its order instead of its index."""
    base, meas = split_measurement(name)
    suffix = f" (measurement {meas + 1})" if meas is not None else ""
    if base in _SPECIAL:
        label, unit = _SPECIAL[base]
        return label + suffix, unit
    m = re.fullmatch(r"housing\.harmonics\.(\d+)\.(order|amplitude|phase)", base)
    if m:
        j, what = int(m.group(1)), m.group(2)
        unit = {"order": "-", "amplitude": "m", "phase": "rad"}[what]
        if harmonics is not None and j < len(harmonics):
            k, _, gamma = harmonics[j]
            part = {"amplitude": f"radial amplitude A{int(k)}", "order": "order",
                    "phase": "phase γ"}[what]
            return f"housing harmonic k = {int(k)} (γ = {gamma:.4g} rad), {part}{suffix}", unit
        return f"housing harmonic slot {j}, {what}{suffix}", unit
    m = re.fullmatch(r"effects\.vane_friction_factor\.(\d+)", base)
    if m:
        return f"housing-COF factor of vane {m.group(1)}{suffix}", "-"
    q = _registry_entry(base)
    label = _CONFIG_DOC.get(base) or (f"{base} ({q.doc})" if q is not None and q.doc else base)
    return label + suffix, (q.unit if q is not None else "?")


def display_scale(unit: str, value: float | None) -> tuple[float, str]:
    """(factor, unit shown): lengths in mm or µm, everything else in SI."""
    if unit == "m" and value is not None and math.isfinite(value):
        return (1e6, "µm") if abs(value) < 1e-3 else (1e3, "mm")
    return 1.0, UNIT_TEXT.get(unit, unit)


# engineering units: SI unit -> [(smallest magnitude, factor, unit shown)], first match wins
_ENGINEERING = {
    "m": [(1e-3, 1e3, "mm"), (0.0, 1e6, "µm")],
    "kg": [(1.0, 1.0, "kg"), (0.0, 1e3, "g")],
    "Pa": [(1e6, 1e-6, "MPa"), (1e3, 1e-3, "kPa"), (0.0, 1.0, "Pa")],
    "Pa·m/s": [(1e6, 1e-6, "MPa·m/s"), (1e3, 1e-3, "kPa·m/s"), (0.0, 1.0, "Pa·m/s")],
    "W": [(1e3, 1e-3, "kW"), (1.0, 1.0, "W"), (0.0, 1e3, "mW")],
    "N·m": [(0.1, 1.0, "N·m"), (0.0, 1e3, "mN·m")],
    "N·m/A": [(0.1, 1.0, "N·m/A"), (0.0, 1e3, "mN·m/A")],
    "kg/s": [(1e-3, 1e3, "g/s"), (0.0, 1e6, "mg/s")],
    "m³/s": [(0.0, 6e4, "L/min")],
    "m^3": [(1e-3, 1e3, "L"), (0.0, 1e6, "cm³")],
}


def engineering_scale(unit: str, values) -> tuple[float, str]:
    """(factor, unit shown) so that the largest finite |value| x factor reads well: mm or µm for a
    length, g for a small mass, kPa, mN·m, L/min; units without a rule stay SI."""
    shown = UNIT_TEXT.get(unit, unit)
    rules = _ENGINEERING.get(shown) or _ENGINEERING.get(unit)
    if not rules:
        return 1.0, shown
    v = np.abs(np.asarray(values, dtype=float).ravel())
    v = v[np.isfinite(v) & (v > 0)]
    size = float(v.max()) if v.size else 0.0
    return next((f, u) for lo, f, u in rules if size >= lo)


def _decimals(value, stderr, digits):
    """Decimals that show the standard error to `digits` significant digits and a value larger
    than it to at least 4; None when fixed point would need more than 7 (then significant digits)."""
    e = math.floor(math.log10(stderr)) - (digits - 1)
    dec = max(0, -e)
    if abs(value) >= stderr and math.floor(math.log10(abs(value))) - e < 3:
        dec = max(dec, 3 - math.floor(math.log10(abs(value))))
    return None if dec > 7 or abs(value) >= 1e7 or stderr >= 1e7 else dec


def _sig(value, stderr, digits):
    """Significant digits of the value that reach the standard error's last shown digit."""
    if value == 0:
        return digits
    return int(min(15, max(4, math.floor(math.log10(abs(value))) - math.floor(math.log10(stderr)) + digits)))


def fmt_estimate(value, stderr, digits: int = 2) -> str:
    """'0.202945 ± 0.000091': the value rounded to the standard error's `digits` significant
    digits (at least 4 significant digits of the value)."""
    if value is None:
        return "not identifiable"
    if stderr is None or not math.isfinite(stderr) or stderr <= 0:
        return f"{value:.6g}"
    dec = _decimals(value, stderr, digits)
    if dec is None:
        return f"{value:#.{_sig(value, stderr, digits)}g} ± {stderr:#.{digits}g}"
    return f"{value:.{dec}f} ± {stderr:.{dec}f}"


def fmt_interval(lower, upper, stderr, digits: int = 2) -> str:
    """'0.202766 … 0.203125' with as many digits as the estimate shows."""
    if lower is None or upper is None:
        return "—"
    if stderr is None or not math.isfinite(stderr) or stderr <= 0:
        return f"{lower:.6g} … {upper:.6g}"
    mid = 0.5 * (lower + upper)
    dec = _decimals(mid, stderr, digits)
    if dec is None:
        n = _sig(mid, stderr, digits)
        return f"{lower:#.{n}g} … {upper:#.{n}g}"
    return f"{lower:.{dec}f} … {upper:.{dec}f}"


def fmt_number(x, sig: int = 6) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    if isinstance(x, (int,)) and not isinstance(x, bool):
        return str(x)
    return f"{x:.{sig}g}".replace("e-0", "e-").replace("e+0", "e+")


def resolution(unit: str) -> float:
    """The smallest magnitude of a quantity in `unit` (N·m, W, N, m, Pa·m/s) the solvers resolve:
    below it a value is the round-off of zero (a concentric pump's torque ripple is ~1e-16 N·m).
    0.0 for a unit without a stated resolution."""
    from .tolerances import DESIGN_CONSTANT_ABS

    return DESIGN_CONSTANT_ABS.get(unit, 0.0)


def resolved(x, unit: str, scale: float = 0.0):
    """`x` as a reader should see it: 0.0 when it is below the solvers' resolution for `unit` plus
    DESIGN_CONSTANT_REL of `scale` (the size of the quantity `x` is a spread or change of), else
    `x` unchanged (also None and NaN)."""
    from .tolerances import DESIGN_CONSTANT_REL

    if x is None or isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        return x
    limit = resolution(unit) + DESIGN_CONSTANT_REL * abs(scale if scale is not None and math.isfinite(scale) else 0.0)
    return 0.0 if abs(x) <= limit else x


def fmt_limit(x, sig: int = 6) -> str:
    """A bound or limit that may be absent: 'none' instead of Python's None."""
    return "none" if x is None else fmt_number(x, sig)


def sha256(path) -> str | None:
    try:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        return h.hexdigest()
    except OSError:
        return None


def samples_sha256(d) -> str:
    """SHA-256 of a Dataset's time, torque, speed and angle samples (float64, in that order)."""
    h = hashlib.sha256()
    for name in ("time", "torque", "speed", "angle"):
        a = getattr(d, name, None)
        if a is not None:
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return h.hexdigest()


def command_line(argv=None) -> str:
    """The command that made a result, as the user typed it ('pumpsim sweep study.toml ...')."""
    argv = list(sys.argv if argv is None else argv)
    path = Path(argv[0]) if argv and argv[0] else Path("python")
    if path.name == "__main__.py":  # python -m pkg
        prog = ["pumpsim"] if path.parent.name == "pumpsim" else ["python", "-m", path.parent.name]
        return shlex.join([*prog, *argv[1:]])
    return shlex.join([path.name, *argv[1:]])


def provenance(cfg=None, data=None, kernel_key=None, files=(), command=None) -> list[tuple[str, str]]:
    """What a reader needs to reproduce a result: data file(s) and their SHA-256, the config (name,
    path, SHA-256), other input `files` ([(label, path)], e.g. a study file) and their SHA-256, the
    compiled kernel's cache key (or keys), the pumpsim version, the date (UTC) and the command.
    `data`: a Dataset, a path, or a list of them."""
    from . import __version__

    rows = []
    for label, path in files:
        rows.append((label, str(Path(path).resolve())))
        rows.append((f"{label} SHA-256", sha256(path) or "(file not readable)"))
    items = data if isinstance(data, (list, tuple)) else ([data] if data is not None else [])
    for i, d in enumerate(items):
        src = getattr(d, "source", d)
        tag = "data file" if len(items) == 1 else f"data file {i + 1}"
        p = Path(str(src)) if src else None
        if p is not None and p.is_file():
            rows.append((tag, str(p.resolve())))
            rows.append((f"{tag} SHA-256", sha256(p)))
        else:  # arrays made in memory: the hash of the samples identifies them
            rows.append((tag, "(arrays passed in memory)" + (f", source '{src}'" if src else "")))
            rows.append((f"{tag} SHA-256", f"{samples_sha256(d)} (of the samples)"))
        n = getattr(d, "n", None)
        if n is not None:
            rows.append((f"{tag} samples", str(n)))
    if cfg is not None:
        rows.append(("config", f"{cfg.name}" + (f" ({Path(cfg.path).resolve()})" if cfg.path else "")))
        if cfg.path and sha256(cfg.path):
            rows.append(("config SHA-256", sha256(cfg.path)))
    if kernel_key is None and cfg is not None:
        kernel_key = kernel_key_of(cfg)
    if isinstance(kernel_key, (list, tuple)):
        kernel_key = ", ".join(k for k in kernel_key if k)
    if kernel_key:
        rows.append(("compiled kernel", kernel_key))
    rows.append(("pumpsim version", __version__))
    rows.append(("date (UTC)", _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S")))
    rows.append(("command", command or command_line()))
    return rows


def kernel_key_of(cfg, model: str = "constrained") -> str | None:
    """Variant and cache key of the compiled kernel the config selects for `model` (constrained,
    contact, or pneumatic: the pump-down's gas model) (never builds one)."""
    try:
        from .kernels import load_kernels
        from .kernels.pneumatic import structure_of

        st = structure_of(cfg) if model == "pneumatic" else cfg.parameters(model).structure
        return f"{st.variant}-{load_kernels(st, build=False).key}"
    except Exception:  # provenance must never break a report  # noqa: BLE001
        return None


def parameter_text(name, value, stderr) -> str:
    """'mu 0.16999 ± 0.00038', 'housing centre x … 12.1 ± 0.4 µm': name, estimate ± s.e., unit."""
    if value is None:
        return f"{name} not identifiable"
    _, unit = describe(name)
    f, shown = display_scale(unit, value)
    text = f"{name} {fmt_estimate(value * f, None if stderr is None else stderr * f)}"
    return text if shown in ("–", "?") else f"{text} {shown}"
