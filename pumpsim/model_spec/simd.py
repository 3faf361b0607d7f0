"""Where a variant's SIMD library lives and when it may be loaded (the scalar library's rules are
in manifest.py; these add the CPU).

The SIMD library (codegen/simd.py) is compiled with -march=native, so besides manifest.py's rules
(key over the C source and options, library hash, source fingerprint) it may run only on a CPU
with the same instruction-set flags and the C library whose vector math it calls: both are among
its options, hence in its key, and compared with this machine's at load time -- a worker on
another CPU builds its own.
"""
from __future__ import annotations

import hashlib
import os
import platform
from dataclasses import dataclass

from . import manifest as mf

# -O3 -fopenmp-simd: honour `omp simd`; -fno-math-errno: libm calls are pure (vectorisable and
# hoistable); -march=native: AVX2/AVX-512 of the building CPU; -ffp-contract=fast: a*b+c as one
# FMA. No -ffast-math: the NaN tests (fmax/fmin, consistency checks) and IEEE division stay.
SIMD_CFLAGS = ["-O3", "-march=native", "-fopenmp-simd", "-fno-math-errno", "-ffp-contract=fast",
               "-fPIC", "-shared", "-std=gnu99"]
LIBRARY = "pumpsim_simd"
# The reduced entry points beside the full one (codegen/simd.py): the vane outputs each computes
# and stores after the torque, in this order. "torque": the fits' model torque alone (one output
# row instead of 1 + 17 N); "reported": what every simulation evaluates up front -- the spec's
# per-vane columns and what the warnings read (pumpsim.result.REPORTED).
SUBSETS = {"torque": (),
           "reported": ("s", "sdot", "normal", "slot1", "slot2", "n_consistent", "ambiguity", "position_residual")}


@dataclass(frozen=True)
class SimdVariant:
    """The SIMD library's name in generated/: <variant>-simd-<key>."""

    base: str

    @property
    def variant(self) -> str:
        return f"{self.base}-simd"


def simd_variant(structure) -> SimdVariant:
    return SimdVariant(structure.variant)


def cpu_signature() -> str:
    """Hash of this CPU's instruction-set flags (/proc/cpuinfo; the platform's processor name
    elsewhere)."""
    text = ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith(("flags", "Features")):
                    text = " ".join(sorted(line.split(":", 1)[1].split()))
                    break
    except OSError:
        pass
    text = text or f"{platform.machine()} {platform.processor()}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def libc_version() -> str:
    try:
        return os.confstr("CS_GNU_LIBC_VERSION") or "unknown"
    except (ValueError, OSError, AttributeError):
        return " ".join(platform.libc_ver())


def simd_options(native: str) -> dict:
    """The options a SIMD library is built with; `native` is what gcc resolves -march=native to."""
    return {"simd_cflags": SIMD_CFLAGS, "native": native, "cpu": cpu_signature(), "libc": libc_version()}


def runs_here(manifest: dict) -> bool:
    o = manifest.get("options", {})
    return (o.get("simd_cflags") == SIMD_CFLAGS and o.get("cpu") == cpu_signature()
            and o.get("libc") == libc_version())


def find_simd(structure, casadi_version: str, fingerprint: str | None):
    """(folder, manifest) of a trusted SIMD build of `structure` for this CPU, or (None, None)."""
    sv = simd_variant(structure)
    for folder in sorted(mf.generated_dir().glob(f"{sv.variant}-*")):
        m = mf.trusted_manifest(folder, sv.variant, casadi_version, fingerprint)
        if m is not None and runs_here(m):
            return folder, m
    return None, None
