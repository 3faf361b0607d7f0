"""Kernel-only measurements for the inverse-dynamics bench: the scalar library's generated
`inverse_dynamics` and the SIMD library, each called from a small C program on the same samples (no
Python, no CasADi runtime), timed and -- when valgrind is installed -- counted in instructions with
callgrind. Callgrind (3.19) cannot run AVX-512 code, so instruction counts are taken from an AVX2
build of the same SIMD source (-mno-avx512f: 4 lanes instead of 8); the split by function shows
where the instructions go (vector libm vs the model's arithmetic)."""
from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

_COMMON = r"""
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
static double *samples(long n, double speed) {  /* theta over 50 revolutions, omega, omegadot = 0 */
  double *x = malloc(3 * n * sizeof(double));
  for (long i = 0; i < n; ++i) { x[i] = 2 * M_PI * 50 * i / (n - 1); x[n + i] = speed; x[2 * n + i] = 0; }
  return x;
}
static double *read_p(const char *s, int np) {
  double *p = malloc(np * sizeof(double));
  for (int q = 0; q < np; ++q) p[q] = strtod(s, (char **)&s);
  return p;
}
"""

SCALAR_MAIN = _COMMON + r"""
typedef long long ci;
typedef int (*fn_t)(const double **, double **, ci *, double *, int);
typedef int (*work_t)(ci *, ci *, ci *, ci *);
int main(int argc, char **argv) {  /* lib n reps speed nvanes nouts np "p..." */
  void *h = dlopen(argv[1], RTLD_NOW);
  if (!h) { fprintf(stderr, "%s\n", dlerror()); return 1; }
  fn_t f = (fn_t)dlsym(h, "inverse_dynamics");
  work_t wk = (work_t)dlsym(h, "inverse_dynamics_work");
  long n = atol(argv[2]); int reps = atoi(argv[3]), N = atoi(argv[5]), NO = atoi(argv[6]), np = atoi(argv[7]);
  double *x = samples(n, atof(argv[4])), *p = read_p(argv[8], np);
  ci sz_arg, sz_res, sz_iw, sz_w;
  wk(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const double **arg = malloc((sz_arg + 4) * sizeof(double *));
  double **res = malloc((sz_res + NO + 1) * sizeof(double *));
  ci *iw = malloc((sz_iw + 1) * sizeof(ci));
  double *w = malloc((sz_w + 1) * sizeof(double));
  double *out = malloc((1 + (long)NO * N) * n * sizeof(double));
  double best = 1e30;
  for (int r = 0; r < reps; ++r) {
    double t0 = now();
    for (long i = 0; i < n; ++i) {
      arg[0] = x + i; arg[1] = x + n + i; arg[2] = x + 2 * n + i; arg[3] = p;
      double *o = out + i * (1 + (long)NO * N);  /* one sample's outputs together */
      res[0] = o;
      for (int j = 0; j < NO; ++j) res[1 + j] = o + 1 + j * N;
      if (f(arg, res, iw, w, 0)) return 1;
    }
    double t = now() - t0;
    if (t < best) best = t;
  }
  printf("%.9g %.17g\n", best, out[0]);
  return 0;
}
"""

SIMD_MAIN = _COMMON + r"""
int pumpsim_simd_blocks(long, const double *, const double *, const double *, const double *, long, double *, long);
int main(int argc, char **argv) {  /* n reps speed rows np "p..." */
  long n = atol(argv[1]); int reps = atoi(argv[2]), rows = atoi(argv[4]), np = atoi(argv[5]);
  double *x = samples(n, atof(argv[3])), *p = read_p(argv[6], np);
  double *out = malloc((long)rows * n * sizeof(double));
  double best = 1e30;
  for (int r = 0; r < reps; ++r) {
    double t0 = now();
    if (pumpsim_simd_blocks(n, x, x + n, x + 2 * n, p, n, out, n)) return 1;
    double t = now() - t0;
    if (t < best) best = t;
  }
  printf("%.9g %.17g\n", best, out[0]);
  return 0;
}
"""


def _compile(cmd):
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd[:3])}...: {proc.stderr[-1500:]}")


def _callgrind(cmd, tmp: Path, tag: str) -> dict:
    """Total instructions and the share in vector/scalar libm functions."""
    out = tmp / f"callgrind.{tag}"
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *cmd],
                   capture_output=True, text=True, check=True)
    ann = subprocess.run(["callgrind_annotate", "--threshold=100", str(out)], capture_output=True,
                         text=True, check=True).stdout
    total = int(re.search(r"([\d,]+).*PROGRAM TOTALS", ann).group(1).replace(",", ""))
    libm = 0
    for line in ann.splitlines():
        m = re.match(r"\s*([\d,]+) .*?\s(\S+)$", line)
        if m and re.search(r"libmvec|libm\.so|_ZGV|\b(sin|cos|atan2|__sin|__cos|__atan2)", line):
            libm += int(m.group(1).replace(",", ""))
    return {"instructions": total, "libm_instructions": libm}


def vector_loop(lib: Path) -> dict:
    """Static instruction count of the widest vector loop that calls vector libm (the vane body,
    one design): instructions and libm calls per iteration, and per sample (/ lanes). Callgrind
    cannot run AVX-512 code; this counts what the CPU runs per iteration, libm calls as one each."""
    dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(lib)], capture_output=True, text=True,
                         check=True).stdout
    ins = [(int(m.group(1), 16), m.group(2), m.group(3)) for m in
           re.finditer(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", dis, re.M)]
    where = {a: i for i, (a, _, _) in enumerate(ins)}
    best = None
    for i, (a, op, arg) in enumerate(ins):
        m = re.match(r"([0-9a-f]+) ", arg) if op.startswith("j") else None
        if not m or int(m.group(1), 16) >= a or int(m.group(1), 16) not in where:
            continue
        body = ins[where[int(m.group(1), 16)]:i + 1]
        calls = [x[2] for x in body if x[1] == "call"]
        if not calls or not all("_ZGV" in c for c in calls):
            continue
        lanes = 8 if any("zmm" in x[2] for x in body) else 4
        if best is None or (lanes, -len(body)) > (best["lanes"], -best["instructions"]):
            best = {"instructions": len(body), "libm_calls": len(calls), "lanes": lanes,
                    "instructions_per_sample": len(body) / lanes}
    return best or {}


def measure(kern, fast, p, speed, n=100_000, reps=5, count_n=10_000) -> dict:
    """Time the scalar function in a C loop and the SIMD library from C on n samples; count
    instructions per sample on count_n samples (difference of two runs removes start-up)."""
    from pumpsim.codegen import build, simd

    N, NO = fast.vanes, len(fast.outputs) - 1
    pstr = " ".join(repr(float(v)) for v in p)
    res = {}
    tmp = Path(tempfile.mkdtemp(prefix="pumpsim-kernel-loops-"))
    try:
        (tmp / "scalar.c").write_text(SCALAR_MAIN)
        (tmp / "simd_main.c").write_text(SIMD_MAIN)
        src = fast.folder / "pumpsim_simd.c"
        flags = [f for f in simd.SIMD_CFLAGS if f not in ("-fPIC", "-shared")]
        _compile([build.CC, "-O2", str(tmp / "scalar.c"), "-o", str(tmp / "scalar"), "-ldl", "-lm"])
        _compile([build.CC, *flags, str(src), str(tmp / "simd_main.c"), "-o", str(tmp / "simd"), "-lm"])
        _compile([build.CC, *flags, "-mno-avx512f", str(src), str(tmp / "simd_main.c"), "-o",
                  str(tmp / "simd_avx2"), "-lm"])
        # the same loops with sin/cos/atan2 replaced by no-ops: the time left is everything but libm
        nolibm = src.read_text().replace('#define pumpsim_zero', '#define sin(x) (x)\n#define cos(x) (x)\n'
                                         '#define atan2(y, x) (y)\n#define pumpsim_zero', 1)
        (tmp / "nolibm.c").write_text(nolibm)
        _compile([build.CC, *flags, str(tmp / "nolibm.c"), str(tmp / "simd_main.c"), "-o",
                  str(tmp / "simd_nolibm"), "-lm"])
        lib = str(kern.folder / kern.manifest["library"])
        cmds = {
            "scalar": lambda n_, r_: [str(tmp / "scalar"), lib, str(n_), str(r_), str(speed), str(N), str(NO),
                                      str(len(p)), pstr],
            "simd": lambda n_, r_: [str(tmp / "simd"), str(n_), str(r_), str(speed), str(fast.rows),
                                    str(len(p)), pstr],
            "simd_nolibm": lambda n_, r_: [str(tmp / "simd_nolibm"), str(n_), str(r_), str(speed),
                                           str(fast.rows), str(len(p)), pstr],
            "simd_avx2": lambda n_, r_: [str(tmp / "simd_avx2"), str(n_), str(r_), str(speed),
                                         str(fast.rows), str(len(p)), pstr],
        }
        for name, cmd in cmds.items():
            out = subprocess.run(cmd(n, reps), capture_output=True, text=True, check=True).stdout.split()
            res[name] = {"seconds": float(out[0]), "samples_per_second": n / float(out[0])}
        res["simd"]["libm_time_share"] = 1 - res["simd_nolibm"]["seconds"] / res["simd"]["seconds"]
        res["simd"]["vane_loop"] = vector_loop(fast.folder / fast.manifest["library"])
        if shutil.which("valgrind") and shutil.which("callgrind_annotate"):
            for name in ("scalar", "simd_avx2"):
                a = _callgrind(cmds[name](count_n, 1), tmp, f"{name}1")
                b = _callgrind(cmds[name](2 * count_n, 1), tmp, f"{name}2")
                per = (b["instructions"] - a["instructions"]) / count_n
                res[name]["instructions_per_sample"] = per
                res[name]["libm_share"] = (b["libm_instructions"] - a["libm_instructions"]) / count_n / per
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return res


def bench_simd(cfg, kern, p, theta, baseline: dict, best_of) -> dict:
    """The SIMD library beside the scalar rows of the inverse-dynamics bench (same samples, same
    run): `baseline` maps those rows' names to seconds."""
    import numpy as np

    from pumpsim.kernels import load_fast_kernel
    from pumpsim.kernels import inverse_dynamics

    fast = load_fast_kernel(kern.structure, fallback=False)  # the bench measures the SIMD library or fails
    n = theta.size
    out = fast.output_array(n)
    rows = {}
    rows["SIMD library, one design"] = best_of(lambda: fast(theta, cfg.speed, 0.0, p, out=out), repeats=5)
    rows["SIMD library, 2 threads"] = best_of(lambda: fast(theta, cfg.speed, 0.0, p, out=out, threads=2),
                                              repeats=5)
    block = 360  # one revolution per design at 1 degree
    names = list(cfg.parameters().names)
    P = np.tile(p, (-(-n // block), 1))
    P[:, names.index("vane.mass")] *= np.linspace(0.8, 1.2, P.shape[0])
    rows[f"SIMD, {P.shape[0]} designs x {block}"] = best_of(
        lambda: fast(theta, cfg.speed, 0.0, P, block=block, out=out), repeats=5)
    Ps = np.repeat(P, block, axis=0)[:n]
    rows["SIMD, p per sample"] = best_of(lambda: fast(theta, cfg.speed, 0.0, Ps, out=out), repeats=5)
    # agreement with the scalar library on every output
    m = min(n, 20000)
    ref = inverse_dynamics(kern, p, theta[:m], cfg.speed, 0.0)
    got = fast(theta, cfg.speed, 0.0, p, out=out)
    agree = max(float(np.max(np.abs(got[k][..., :m] - r)) / max(np.max(np.abs(r)), 1e-300))
                for k, r in ref.items() if k != "position_residual")
    loops = measure(kern, fast, p, cfg.speed, n=n)
    t_simd = rows["SIMD library, one design"]
    t_map, t_np = baseline["compiled C library"], baseline["NumPy (lambdified SymPy)"]
    ratios = {"vs_scalar_map": t_map / t_simd, "vs_numpy": t_np / t_simd,
              "vs_scalar_c_loop": loops["scalar"]["seconds"] / t_simd,
              "c_loops_simd_vs_scalar": loops["scalar"]["seconds"] / loops["simd"]["seconds"]}
    print(f"{'implementation':<28}{'seconds':>10}{'samples/s':>14}")
    for name, t in rows.items():
        print(f"{name:<28}{t:>10.4f}{n / t:>14.3g}")
    print(f"{'scalar function, C loop':<28}{loops['scalar']['seconds']:>10.4f}"
          f"{loops['scalar']['samples_per_second']:>14.3g}")
    print(f"{'SIMD library, C caller':<28}{loops['simd']['seconds']:>10.4f}{loops['simd']['samples_per_second']:>14.3g}")
    print(f"SIMD one design: {n / t_simd:.3g} samples/s (target >= 1e6); vs the compiled library as "
          f"the runtime calls it {ratios['vs_scalar_map']:.1f}x (target >= 5x), vs NumPy "
          f"{ratios['vs_numpy']:.1f}x (target >= 10x), vs the scalar function in a C loop "
          f"{ratios['vs_scalar_c_loop']:.1f}x; max relative difference to the scalar library {agree:.1e}")
    vl = loops["simd"]["vane_loop"]
    print(f"where the SIMD time goes: libm (vector sin/cos/atan2) {100 * loops['simd']['libm_time_share']:.0f} % "
          f"(same loops with libm calls removed: {loops['simd_nolibm']['samples_per_second']:.3g} samples/s); "
          f"vane loop {vl.get('instructions')} instructions + {vl.get('libm_calls')} vector libm calls per "
          f"{vl.get('lanes')} samples")
    if "instructions_per_sample" in loops["scalar"]:
        s, v = loops["scalar"], loops["simd_avx2"]
        print(f"instructions per sample (callgrind): scalar function {s['instructions_per_sample']:.0f} "
              f"({100 * s['libm_share']:.0f} % in libm); SIMD built for AVX2 {v['instructions_per_sample']:.0f} "
              f"({100 * v['libm_share']:.0f} % in libm), {v['samples_per_second']:.3g} samples/s")
    return {"rows": {k: {"seconds": t, "samples_per_second": n / t} for k, t in rows.items()},
            "c_loops": loops, "ratios": ratios, "max_rel_difference_vs_scalar": agree,
            "library": {"key": fast.manifest["key"], **fast.manifest["options"],
                        **{k: fast.manifest[k] for k in ("vector_symbols", "vectorized_loops")}}}
