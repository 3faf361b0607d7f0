"""A second, SIMD library of the constrained model's inverse dynamics: many samples per call, several
samples per instruction.

The scalar library (codegen.build) evaluates one sample per call; CasADi's map calls it once per
sample and the runtime converts every output from DM. Here the per-vane SX body is written out from
CasADi's own instruction list (`Function.instruction_*`, not by rewriting generated C text) as the
body of one `#pragma omp simd` loop over samples, inputs and outputs being arrays with one value per
sample. gcc then evaluates 4 (AVX2) or 8 (AVX-512) samples per instruction and calls glibc's vector
sin/cos/atan2 (libmvec) -- which it does only when

- the math functions are declared `simd` (glibc declares them so only under -ffast-math, which would
  also drop the NaN tests the model relies on): declared here, compiled with -fno-math-errno;
- sin(x) and cos(x) of one argument are not fused into sincos, which has no vector call in gcc's
  eyes: every cos argument gets `+ zero`, a volatile 0.0 read once (x + 0.0 == x, cos is even);
- fmin/fmax/sign are selects, not calls (NaN behaviour kept: fmax returns the non-NaN operand), and
  every select is a branch-free bit blend (AVX2 has no masks to hide a branch's trapping operations).

A divisor that divides several quotients is inverted once (simd_emit.shared_reciprocals; a rounding
of the last bit against the scalar library). The rewrite is made on the SX graph, so the Jacobian
entries, taken from the same graph, keep the torque entry's bits.

The build fails unless gcc reports both vane loops vectorised and vector-math symbols (`_ZGV...`)
are referenced: a silently scalar loop is not a SIMD library. Key and trust follow the scalar
library's contract (pumpsim.model_spec.manifest: C source, options, CasADi, source fingerprint,
library hash); the options add the resolved -march=native target, the CPU's flags and the C
library (pumpsim.model_spec.simd), so a machine with another CPU builds its own.

Exported C functions (all arrays float64, outputs row-major (1 + 17 N, ld): torque, then each vane
output for vanes 0..N-1; `ld` lets callers write a column range of a larger array):
  pumpsim_simd_blocks(n, theta, omega, omegadot, p, block, out, ld): p is (ceil(n / block), n_p),
      one parameter vector per block of `block` consecutive samples (block = n: one design);
  pumpsim_simd_samples(n, theta, omega, omegadot, pt, pld, out, ld): pt is (n_p, pld), one
      parameter vector per sample, stored by parameter.
  pumpsim_simd_<subset>_blocks / _samples for each reduced set of model_spec.simd.SUBSETS: the same
      arguments, `out` (1 + len(subset) N, ld) with the torque and the subset's vane outputs only
      (the vane body restricted to them: the torque alone is 1,124 of the 4-vane ellipse's 1,342
      vane instructions, and stores one row).
  pumpsim_simd_jac_blocks / _samples: the torque and its derivatives along directions in (theta,
      omega, omegadot, p): codegen/simd_jacobian.py.
  pumpsim_simd_reduce_blocks: a design study's per-design numbers, reduced in cache from each
      block's outputs: codegen/simd_reduce.py.
"""
from __future__ import annotations

import functools
import os
import re
import string
import subprocess
import time
from pathlib import Path

import casadi as ca

from pumpsim.errors import CodegenError
from pumpsim.model_spec.outputs import VANE_OUTPUTS
from pumpsim.model_spec.simd import LIBRARY, SIMD_CFLAGS, SUBSETS, simd_options, simd_variant

from .builder import Builder
from .install import CC, install_library
from .simd_emit import HELPERS, emit_loop, shared_reciprocals
from .simd_jacobian import jacobian_source
from .simd_reduce import reduction_source

CHUNK = 512  # samples per pass over the vanes: the vanes' torque shares stay in L1/L2 for the sum
VECTOR_FUNCTIONS = ("sin", "cos", "atan2")  # the model's transcendentals with a libmvec variant

# -- the model's functions, from the same builder and helpers as the scalar library -----------------
def simd_functions(structure):
    """SX functions the library loops over: the vane body (the scalar library's, its shared divisors
    as reciprocals: simd_emit.shared_reciprocals), the
    per-vane arguments taken from p (slot angle, friction factor) and the rotor's torque sum."""
    if structure.model != "constrained":
        raise ValueError("the SIMD library covers the constrained model's inverse dynamics")
    b = Builder(structure)
    vane = shared_reciprocals(b.vane_constrained())
    N = structure.vanes
    args = ca.Function("vane_arguments", [b.p], [b.slot_angles(b.p).T, b.factors(b.p).T],
                       ["p"], ["phi", "factor"])
    wd, shares = ca.SX.sym("omegadot"), ca.SX.sym("torque_share", N)
    # as constrained_model's assemble: rotor inertia, bearing torque and the vanes' shares
    tq = b.pget(b.p, "rotor.inertia") * wd + b.pget(b.p, "operation.bearing_torque") + ca.sum1(shares)
    torque = ca.Function("rotor_torque", [wd, shares, b.p], [tq], ["omegadot", "torque_share", "p"],
                         ["torque"])
    return dict(vane=vane, arguments=args, torque=torque, n_params=len(b.params),
                outputs=("torque", *VANE_OUTPUTS),
                share_index=VANE_OUTPUTS.index("torque_share"))


# One template for every entry point: the full one (sfx "", every vane output stored) and the
# reduced ones of SUBSETS (only their outputs computed and stored; the vanes' torque shares, which
# the rotor sum needs, kept in a chunk-sized scratch when the subset does not store them).
_DRIVER = string.Template(r"""
/* One design over samples [0, n): theta.. point at sample 0, p at its parameter vector. */
static void one_design$sfx(long n, const double *theta, const double *omega, const double *omegadot,
                       const double *p, double *out, long ld) {
  double arg[2 * NV];$scratch
  const double *ain[NP];
  double *aout[2 * NV];
  for (int q = 0; q < NP; ++q) ain[q] = p + q;
  for (int q = 0; q < 2 * NV; ++q) aout[q] = arg + q;
  loop_arguments_shared(1, ain, aout);
  const double *vin[5 + NP];
  double *vout[$no];
  const double *tin[1 + NV + NP];
  for (int q = 0; q < NP; ++q) vin[5 + q] = tin[1 + NV + q] = p + q;
  for (long lo = 0; lo < n; lo += CHUNK) {
    long m = n - lo < CHUNK ? n - lo : CHUNK;
    vin[0] = theta + lo; vin[1] = omega + lo; vin[2] = omegadot + lo;
    for (int k = 0; k < NV; ++k) {
      vin[3] = arg + k; vin[4] = arg + NV + k;
      for (int j = 0; j < $stored; ++j) vout[j] = out + (1 + (long)j * NV + k) * ld + lo;$scratch_out
      loop_vane${sfx}_shared(m, vin, vout);
    }
    tin[0] = omegadot + lo;
    for (int k = 0; k < NV; ++k) tin[1 + k] = $share;
    double *tout[1] = {out + lo};
    loop_torque_shared(m, tin, tout);
  }
}

int pumpsim_simd${sfx}_blocks(long n, const double *theta, const double *omega, const double *omegadot,
                        const double *p, long block, double *out, long ld) {
  if (n < 0 || block < 1 || ld < n) return 1;
  for (long b = 0; b * block < n; ++b) {
    long lo = b * block, m = n - lo < block ? n - lo : block;
    one_design$sfx(m, theta + lo, omega + lo, omegadot + lo, p + b * NP, out + lo, ld);
  }
  return 0;
}

int pumpsim_simd${sfx}_samples(long n, const double *theta, const double *omega, const double *omegadot,
                         const double *pt, long pld, double *out, long ld) {
  if (n < 0 || pld < n || ld < n) return 1;
  double arg[2 * NV][CHUNK];$scratch
  const double *ain[NP], *vin[5 + NP], *tin[1 + NV + NP];
  double *aout[2 * NV], *vout[$no];
  for (int q = 0; q < 2 * NV; ++q) aout[q] = arg[q];
  for (long lo = 0; lo < n; lo += CHUNK) {
    long m = n - lo < CHUNK ? n - lo : CHUNK;
    for (int q = 0; q < NP; ++q) ain[q] = vin[5 + q] = tin[1 + NV + q] = pt + q * pld + lo;
    loop_arguments_samples(m, ain, aout);
    vin[0] = theta + lo; vin[1] = omega + lo; vin[2] = omegadot + lo;
    for (int k = 0; k < NV; ++k) {
      vin[3] = arg[k]; vin[4] = arg[NV + k];
      for (int j = 0; j < $stored; ++j) vout[j] = out + (1 + (long)j * NV + k) * ld + lo;$scratch_out
      loop_vane${sfx}_samples(m, vin, vout);
    }
    tin[0] = omegadot + lo;
    for (int k = 0; k < NV; ++k) tin[1 + k] = $share;
    double *tout[1] = {out + lo};
    loop_torque_samples(m, tin, tout);
  }
  return 0;
}
""")


def vane_subset(vane: ca.Function, stored) -> ca.Function:
    """The vane body with only the outputs `stored` (in that order) and the torque share last when
    not among them: CasADi keeps only the instructions these outputs depend on."""
    keep = list(stored) + ([] if "torque_share" in stored else ["torque_share"])
    sx = vane.sx_in()
    outs = dict(zip(vane.name_out(), vane.call(sx)))
    return ca.Function(f"{vane.name()}_{len(stored)}", sx, [outs[k] for k in keep], vane.name_in(), keep)


def _driver(sfx: str, stored: list, vane: ca.Function) -> str:
    """The C entry points of one output set (see _DRIVER)."""
    share_row = "out + (1 + (long){} * NV + k) * ld + lo"
    if sfx == "":  # the full set: the vane function's own outputs
        return _DRIVER.substitute(sfx="", scratch="", no="NO", stored="NO", scratch_out="",
                                  share=share_row.format("SHARE"))
    if "torque_share" in stored:
        return _DRIVER.substitute(sfx=sfx, scratch="", no=vane.n_out(), stored=len(stored), scratch_out="",
                                  share=share_row.format(stored.index("torque_share")))
    return _DRIVER.substitute(sfx=sfx, scratch="\n  double share[NV][CHUNK];", no=vane.n_out(),
                              stored=len(stored), scratch_out=f"\n      vout[{len(stored)}] = share[k];",
                              share="share[k]")


def generate_source(structure) -> tuple[str, dict]:
    fns = simd_functions(structure)
    N, NP = structure.vanes, fns["n_params"]
    vane, args, torque = fns["vane"], fns["arguments"], fns["torque"]
    decl = "".join(f"double {fn}({', '.join(['double'] * (2 if fn == 'atan2' else 1))}) "
                   f"__attribute__((simd(\"notinbranch\")));\n" for fn in VECTOR_FUNCTIONS)
    parts = [
        f"/* pumpsim SIMD inverse dynamics, {structure.variant}; generated by codegen/simd.py */",
        "#include <math.h>", HELPERS, decl,
        "static volatile double pumpsim_zero_v = 0.0;",
        "#define pumpsim_zero pumpsim_zero_v",
        f"#define NV {N}\n#define NP {NP}\n#define NO {vane.n_out()}\n#define SHARE {fns['share_index']}"
        f"\n#define CHUNK {CHUNK}",
        # shared: theta, omega, omegadot per sample, the rest one value; samples: everything per sample
        emit_loop(vane, "loop_vane_shared", {0, 1, 2}),
        emit_loop(vane, "loop_vane_samples", set(range(vane.n_in()))),
        emit_loop(args, "loop_arguments_shared", set()),
        emit_loop(args, "loop_arguments_samples", {0}),
        emit_loop(torque, "loop_torque_shared", {0, 1}),
        emit_loop(torque, "loop_torque_samples", {0, 1, 2}),
        _driver("", fns["outputs"][1:], vane),
    ]
    for name, stored in SUBSETS.items():
        sub = vane_subset(vane, stored)
        parts += [emit_loop(sub, f"loop_vane_{name}_shared", {0, 1, 2}),
                  emit_loop(sub, f"loop_vane_{name}_samples", set(range(sub.n_in()))),
                  _driver(f"_{name}", list(stored), sub)]
    jac_src, jac_info = jacobian_source(fns)
    red_src, red_info = reduction_source(fns["outputs"][1:])
    src = "\n".join(parts + [jac_src, red_src])
    lines = src.splitlines()
    starts = {m.group(1): i + 1 for i, ln in enumerate(lines) for m in [re.match(r"static void (loop_\w+)\(", ln)] if m}
    ends = {name: next(i + 1 for i in range(a, len(lines)) if lines[i] == "}") for name, a in starts.items()}
    info = {"vanes": N, "n_params": NP, "outputs": list(fns["outputs"]), "chunk": CHUNK,
            "subsets": {name: list(stored) for name, stored in SUBSETS.items()},
            "vane_instructions": vane.n_instructions(), "jacobian": jac_info, "reductions": red_info,
            "loop_lines": {name: [starts[name], ends[name]] for name in starts}}
    return src, info


def unvectorised_loops(loop_lines: dict, report: str, names=None):
    """The loops among `names` (default: every vane loop, in source order) that gcc's
    -fopt-info-vec-optimized report does not name as vectorised (a loop is found by the source
    lines of its function)."""
    if names is None:
        names = sorted((nm for nm in loop_lines if nm.startswith("loop_vane")), key=lambda nm: loop_lines[nm][0])
    done = [int(m.group(1)) for m in re.finditer(r":(\d+):\d+: optimized: loop vectorized", report)]
    return [nm for nm in names if not any(loop_lines[nm][0] <= ln <= loop_lines[nm][1] for ln in done)]


# -- build -----------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def native_target() -> str:
    """The options gcc derives from -march=native on this CPU (-march, -mtune and every ISA
    -m flag). "" if gcc cannot say."""
    try:
        proc = subprocess.run([CC, *SIMD_CFLAGS, "-###", "-x", "c", "-c", os.devnull, "-o",
                               os.devnull], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    for line in proc.stderr.splitlines():
        if "cc1" in line:
            return " ".join(t.strip('"') for t in line.split() if re.match(r'"?-m(?!64)', t))
    return ""


def vector_symbols(lib: Path) -> list[str]:
    """Vector-math entry points (_ZGV...) the library calls."""
    try:
        out = subprocess.run(["nm", "-D", "--undefined-only", str(lib)], capture_output=True,
                             text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return []
    return sorted({ln.split()[-1].split("@")[0] for ln in out.splitlines() if "_ZGV" in ln})


def _compile(structure, source: Path, info: dict, log) -> tuple[Path, dict, float]:
    lib = source.with_suffix(".so")
    log(f"compiling the SIMD library of {structure.variant}")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([CC, *SIMD_CFLAGS, "-fopt-info-vec-optimized", str(source), "-o",
                               str(lib), "-lm"], capture_output=True, text=True)
    except OSError as e:
        raise CodegenError(f"SIMD library of {structure.variant}: cannot run '{CC}' ({e.strerror})") from None
    if proc.returncode != 0:
        raise CodegenError(f"compiling the SIMD library of {structure.variant} failed:\n{proc.stderr[-2000:]}")
    scalar = unvectorised_loops(info["loop_lines"], proc.stderr)
    if scalar:
        raise CodegenError(f"the SIMD library of {structure.variant}: gcc left {', '.join(scalar)} "
                           f"scalar with {' '.join(SIMD_CFLAGS)} on this CPU ({native_target()[:40]}...)")
    vec = vector_symbols(lib)
    missing = [fn for fn in VECTOR_FUNCTIONS if not any(s.endswith(f"_{fn}") for s in vec)]
    if missing:
        raise CodegenError(f"the SIMD library of {structure.variant} calls no vector {', '.join(missing)}"
                           f" (found {vec or 'none'}): the compiler left its loops scalar")
    loops = re.findall(r":(\d+):\d+: optimized: loop vectorized using (\d+) byte", proc.stderr)
    checks = {"vector_symbols": vec, "vectorized_loops": [f"line {ln}: {b} bytes" for ln, b in loops]}
    return lib, checks, time.perf_counter() - t0


def build_simd(structure, log=None) -> Path:
    """Generate, compile and check the SIMD library; return its folder. The build procedure is
    build_variant's (install.install_library): a key that exists is reused, builds are atomic renames."""
    log = log or (lambda msg: None)
    native = native_target()
    if not native:
        raise CodegenError(f"{CC} cannot resolve -march=native here; no SIMD library")
    info = {}

    def generate(folder):
        src, found = generate_source(structure)
        info.update(found)
        source = folder / f"{LIBRARY}.c"
        source.write_text(src)
        return source, info

    def built(final, t_gen, t_compile, checks):
        log(f"built {final.name} in {t_gen + t_compile:.1f} s (vector calls: {', '.join(checks['vector_symbols'])})")

    return install_library(simd_variant(structure), structure, simd_options(native), generate,
                                 lambda source: _compile(structure, source, info, log), built, log, stage="generate")
