"""Where the pump-down's floor is under CasADi's integrator layer (issue 15, an experiment, not part
of `make bench`): the bundled EVP pump-down integrated by SUNDIALS' CVODES driven directly from a
small C program over the same compiled pump_rhs / pump_rhs_jac (BDF, order <= 3, dense direct
solver, CVODES' own Jacobian reuse, the same tolerances as per-component atol = atol x the
runtime's state scale, a fresh start every 50 output intervals as the runtime does), back to back
with `pumpdown()` through CasADi. Needs the SUNDIALS headers and libraries (Debian:
`apt-get install libsundials-dev`, 6.4); prints one line per path and their ratio.

    .venv/bin/python bench/cvodes_direct.py [--rtol R] [--atol A]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.config import load_config  # noqa: E402
from pumpsim.pneumatics import pumpdown as pdm  # noqa: E402
from pumpsim.pneumatics import run  # noqa: E402
from pumpsim.kernels.pneumatic import kernels, parameter_index, parameter_vector  # noqa: E402
from pumpsim.tolerances import PUMPDOWN_ATOL, PUMPDOWN_RTOL  # noqa: E402

DRIVER = r"""
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunlinsol/sunlinsol_dense.h>
typedef long long ci;
typedef int (*fn_t)(const double **, double **, ci *, double *, int);
static fn_t F, FJ; static const ci *JSP; static double *P, jbuf[4096], w[1 << 16]; static ci iw[1024];
static int NX; static long nrhs, njac;
static int rhs(sunrealtype t, N_Vector y, N_Vector yd, void *u) {
  double *D = N_VGetArrayPointer(yd); const double *a[2] = {N_VGetArrayPointer(y), P};
  double *r[2] = {D, D + NX}; nrhs++; return F(a, r, iw, w, 0);
}
static int jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *u, N_Vector t1, N_Vector t2, N_Vector t3) {
  const double *a[2] = {N_VGetArrayPointer(y), P}; double *r[2] = {jbuf, 0};
  njac++; if (FJ(a, r, iw, w, 0)) return 1;
  SUNMatZero(J);  /* CasADi's compressed column pattern: nrow, ncol, colind[ncol + 1], row[nnz] */
  const ci nc = JSP[1], *col = JSP + 2, *row = JSP + 3 + nc;
  for (ci c = 0; c < nc; c++) for (ci k = col[c]; k < col[c + 1]; k++) SM_ELEMENT_D(J, row[k], c) = jbuf[k];
  return 0;
}
static void add(void *cv, long *st) {
  long s; CVodeGetNumSteps(cv, &s); st[0] += s; CVodeGetNumErrTestFails(cv, &s); st[1] += s;
  CVodeGetNumNonlinSolvConvFails(cv, &s); st[2] += s; CVodeGetNumLinSolvSetups(cv, &s); st[3] += s;
}
int main(int argc, char **argv) {  /* lib rtol atol nx nq np ib chunk dt < x0 p scale m_stop */
  void *h = dlopen(argv[1], RTLD_NOW); if (!h) { puts(dlerror()); return 2; }
  F = (fn_t)dlsym(h, "pump_rhs"); FJ = (fn_t)dlsym(h, "pump_rhs_jac");
  JSP = ((const ci *(*)(ci))dlsym(h, "pump_rhs_jac_sparsity_out"))(0);
  double rtol = atof(argv[2]), atol = atof(argv[3]), dt = atof(argv[9]), stop, v;
  NX = atoi(argv[4]); int n = NX + atoi(argv[5]), np = atoi(argv[6]), ib = atoi(argv[7]), chunk = atoi(argv[8]);
  SUNContext ctx; SUNContext_Create(NULL, &ctx);
  N_Vector y = N_VNew_Serial(n, ctx), av = N_VNew_Serial(n, ctx);
  P = malloc(np * sizeof(double));
  for (int i = 0; i < n; i++) NV_Ith_S(y, i) = 0.0;
  for (int i = 0; i < NX; i++) scanf("%lf", &NV_Ith_S(y, i));
  for (int i = 0; i < np; i++) scanf("%lf", &P[i]);
  for (int i = 0; i < n; i++) { v = 1.0; if (i < NX) scanf("%lf", &v); NV_Ith_S(av, i) = atol * v; }
  scanf("%lf", &stop);
  void *cv = CVodeCreate(CV_BDF, ctx); CVodeInit(cv, rhs, 0.0, y); CVodeSVtolerances(cv, rtol, av);
  SUNMatrix A = SUNDenseMatrix(n, n, ctx); SUNLinearSolver LS = SUNLinSol_Dense(y, A, ctx);
  CVodeSetLinearSolver(cv, LS, A); CVodeSetJacFn(cv, jac); CVodeSetMaxOrd(cv, 3); CVodeSetMaxNumSteps(cv, 2000000);
  struct timespec t0, t1; clock_gettime(CLOCK_MONOTONIC, &t0);
  double prev = NV_Ith_S(y, ib), tt = -1, tr; long st[4] = {0};
  for (long k = 1; k < 100000000; k++) {
    if (CVode(cv, k * dt, y, &tr, CV_NORMAL) < 0) { printf("failed at t = %g\n", tr); return 1; }
    double m = NV_Ith_S(y, ib);
    if (m <= stop) { tt = (k - 1) * dt + dt * (prev - stop) / (prev - m); break; }
    prev = m;
    if (k % chunk == 0) { add(cv, st); CVodeReInit(cv, k * dt, y); }
  }
  clock_gettime(CLOCK_MONOTONIC, &t1); add(cv, st);
  double wall = t1.tv_sec - t0.tv_sec + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
  printf("%.6f %.4f %ld %ld %ld %ld %ld %ld\n", tt, wall, st[0], nrhs, njac, st[3], st[1], st[2]);
  return 0;
}
"""


def direct(cfg, rtol, atol, tmp: Path):
    """Compile the driver, run it on the EVP example; returns its numbers."""
    kern = kernels(cfg)
    p = parameter_vector(cfg)
    st = kern.structure
    x0 = run.initial_state(cfg, kern, p)
    scale = run.state_scale(x0, p, st)
    RT = p[parameter_index(st, "gas.gas_constant")] * p[parameter_index(st, "gas.temperature")]
    stop = cfg.pneumatic.booster_target * p[parameter_index(st, "booster.volume")] / RT
    src, exe = tmp / "cvodes_direct.c", tmp / "cvodes_direct"
    src.write_text(DRIVER)
    subprocess.run(["gcc", "-O2", str(src), "-o", str(exe), "-lsundials_cvodes", "-lsundials_nvecserial",
                    "-lsundials_sunmatrixdense", "-lsundials_sunlinsoldense", "-lsundials_generic",
                    "-ldl", "-lm"], check=True)
    lib = next(Path(kern.folder).glob("*.so"))
    nx, nq = kern["pump_rhs"].size1_out(0), kern["pump_rhs"].size1_out(1)
    ib = 3 + 2 * st.vanes + 2
    args = [str(exe), str(lib), repr(rtol), repr(atol), str(nx), str(nq), str(p.size), str(ib),
            str(run.CHUNK), repr(1 / 2000.0)]
    stdin = " ".join(repr(float(v)) for v in [*x0, *p, *scale, stop])
    out = subprocess.run(args, input=stdin, capture_output=True, text=True, check=True).stdout.split()
    keys = ("time_to_target", "wall", "steps", "rhs", "jac", "setups", "etf", "ncf")
    return dict(zip(keys, (float(out[0]), float(out[1]), *map(int, out[2:8]))))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rtol", type=float, default=PUMPDOWN_RTOL)
    ap.add_argument("--atol", type=float, default=PUMPDOWN_ATOL)
    a = ap.parse_args()
    cfg = load_config(ROOT / "examples" / "evp_booster.toml")
    with tempfile.TemporaryDirectory() as tmp:
        d = direct(cfg, a.rtol, a.atol, Path(tmp))
    t0 = time.perf_counter()
    s = pdm.pumpdown(cfg, rtol=a.rtol, atol=a.atol).summary
    wall = time.perf_counter() - t0
    c = s["solver"]
    print(f"CVODES from C : time to target {d['time_to_target']:.4f} s, {d['wall']:.2f} s wall = "
          f"{d['wall'] / d['time_to_target']:.2f} x real time; {d['steps']} steps, {d['rhs']} rhs, "
          f"{d['jac']} Jacobians ({d['setups']} setups), {d['etf']} error-test and {d['ncf']} Newton "
          f"failures; {d['wall'] / d['steps'] * 1e6:.1f} us/step")
    print(f"CasADi cvodes : time to target {s['time_to_target']:.4f} s, {wall:.2f} s wall = "
          f"{wall / s['duration']:.2f} x real time; {c['nsteps']} steps, {c['nfevals']} rhs, "
          f"{c['njevals']} Jacobians ({c['nlinsetups']} setups), {c['netfails']} error-test and "
          f"{c['nncfails']} Newton failures; {wall / c['nsteps'] * 1e6:.1f} us/step")
    print(f"ratio CasADi / C: {wall / d['wall']:.2f}x wall, "
          f"{wall / c['nsteps'] / (d['wall'] / d['steps']):.2f}x per step")


if __name__ == "__main__":
    main()
