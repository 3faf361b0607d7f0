"""The SIMD library's Jacobian entry points: the rotor torque and its derivatives along any number of
directions in u = (theta, omega, omegadot, p[0..NP-1]), sample-parallel like the torque entries.

The derivatives are CasADi's own, taken on the same SX expressions the torque entries are written
from: per vane, the gradient of its torque share with respect to every input it depends on (one
reverse sweep, ~2.5x the share's instructions, whatever the number of directions), written out by
emit_loop as one `omp simd` loop that stores the share and the gradient's nonzeros for a chunk of
samples; likewise the gradient of the rotor's own terms (inertia, bearing torque). The driver then
contracts the gradients with the directions' seeds: for vane k the seed of each gradient entry is
the direction's component of that input -- for the slot angle and the friction factor, which the
library takes from p (`vane_arguments`), the chain rule through their Jacobian, which is constant
(checked here) and written into the C file. A zero seed costs nothing (a direction that moves the
COFs touches four gradient rows).

Exported (seed: (nd, 3 + NP) row-major, the same directions for every sample; out: (1 + nd, ld),
the torque row -- the torque entry's loops, the same bits -- then one derivative row per direction):
  pumpsim_simd_jac_blocks(n, theta, omega, omegadot, p, block, nd, seed, out, ld)
  pumpsim_simd_jac_samples(n, theta, omega, omegadot, pt, pld, nd, seed, out, ld)
(p and pt as the torque entries'.) Return 0, 1 for bad sizes, 2 when out of memory.
"""
from __future__ import annotations

import string

import casadi as ca

from pumpsim.errors import CodegenError

from .simd_emit import LITERAL_INPUTS, emit_loop

# vane inputs (theta, omega, omegadot, phi, factor, p...) as indices into u = (theta, omega,
# omegadot, p...); phi and factor go through the arguments' Jacobian (ARG below)
_THETA, _PHI, _FACTOR, _P = 0, 3, 4, 5


def gradient_function(f: ca.Function, out: str, wrt: list[int], name: str):
    """(SX function of f's inputs -> (f's output `out`, the nonzeros of its gradient with respect to
    the inputs `wrt`)), and the flat input index (over the `wrt` inputs' nonzeros) of each entry."""
    sx = f.sx_in()
    y = dict(zip(f.name_out(), f.call(sx)))[out]
    x = ca.vertcat(*[sx[i] for i in wrt])
    jac = ca.jacobian(y, x)  # one row: CasADi takes it in reverse mode
    cols = jac.sparsity().get_col()
    nz = [jac.nz[q] for q in range(jac.nnz())]
    return ca.Function(name, sx, [y, ca.vertcat(*nz)], f.name_in(), [out, "gradient"]), cols


def constant_jacobian(f: ca.Function, wrt: int) -> list[list[float]]:
    """The Jacobian of f's outputs (stacked) with respect to its input `wrt`, which must not depend
    on the inputs: the chain rule is then a fixed table in the C file."""
    sx = f.sx_in()
    jac = ca.jacobian(ca.vertcat(*[ca.vec(o) for o in f.call(sx)]), sx[wrt])
    if not jac.is_constant():
        raise CodegenError(f"the SIMD Jacobian needs {f.name()} linear in {f.name_in(wrt)}")
    return ca.DM(jac).full().tolist()


def _c_table(rows) -> str:
    return "{" + ", ".join("{" + ", ".join(repr(float(v)) for v in r) + "}" for r in rows) + "}"


def _c_ints(values) -> str:
    return "{" + ", ".join(str(int(v)) for v in values) + "}"


_JAC = string.Template(r"""
/* -- Jacobian entries (codegen/simd_jacobian.py) -- */
#include <stdlib.h>
#define NG $ng
#define NGT $ngt
static const int vane_grad_input[NG] = $vane_cols;   /* vane input of each gradient row */
static const int rotor_grad_input[NGT] = $rotor_cols; /* 0: omegadot, 1 + q: p[q] */
static const double arg_jac[2 * NV][NP] = $arg_jac; /* d(phi_k, factor_k) / dp */

/* The seed of every gradient row: c[(k nd + d) NG + q] of vane k, ct[d NGT + q] of the rotor. */
static void jac_seeds(long nd, const double *seed, double *c, double *ct) {
  for (long d = 0; d < nd; ++d) {
    const double *u = seed + d * (3 + NP);
    for (int k = 0; k < NV; ++k) {
      double dphi = 0., dfac = 0.;
      for (int q = 0; q < NP; ++q) { dphi += arg_jac[k][q] * u[3 + q]; dfac += arg_jac[NV + k][q] * u[3 + q]; }
      for (int q = 0; q < NG; ++q) {
        int i = vane_grad_input[q];
        c[(k * nd + d) * NG + q] = i < $phi ? u[i] : i == $phi ? dphi : i == $factor ? dfac : u[3 + i - $p];
      }
    }
    for (int q = 0; q < NGT; ++q) ct[d * NGT + q] = u[2 + rotor_grad_input[q]];
  }
}

/* out_d[s] += sum_q c[d][q] g[q][s] over the nonzero seeds */
static void jac_contract(long m, long nd, int ng, const double *c, const double *g, double *out, long ld) {
  for (long d = 0; d < nd; ++d) {
    double *restrict o = out + (1 + d) * ld;
    for (int q = 0; q < ng; ++q) {
      double a = c[d * ng + q];
      if (a == 0.) continue;
      const double *restrict gq = g + (long)q * CHUNK;
      for (long s = 0; s < m; ++s) o[s] += a * gq[s];
    }
  }
}

$drivers
""")

# One chunk of samples [lo, lo + m): every vane's share and gradient, the contraction, the torque.
# `vin`/`tin`/`rin` hold the inputs; the caller set p's and the arguments' pointers.
_CHUNK_BODY = r"""    for (long d = 0; d < nd; ++d) memset(out + (1 + d) * ld + lo, 0, m * sizeof(double));
    vin[0] = theta + lo; vin[1] = omega + lo; vin[2] = omegadot + lo;
    for (int k = 0; k < NV; ++k) {
      $args
      vout[0] = w->share + k * CHUNK;
      for (int q = 0; q < NG; ++q) vout[1 + q] = w->g + q * CHUNK;
      loop_vane_grad_$mode(m, vin, vout);
      jac_contract(m, nd, NG, w->c + k * nd * NG, w->g, out + lo, ld);
    }
    tin[0] = rin[0] = omegadot + lo;
    for (int k = 0; k < NV; ++k) tin[1 + k] = rin[1 + k] = w->share + k * CHUNK;
    double *tout[1] = {out + lo};
    loop_torque_$mode(m, tin, tout);
    rout[0] = w->share + NV * CHUNK;
    for (int q = 0; q < NGT; ++q) rout[1 + q] = w->g + q * CHUNK;
    loop_rotor_grad_$mode(m, rin, rout);
    jac_contract(m, nd, NGT, w->ct, w->g, out + lo, ld);
"""

_DRIVERS = string.Template(r"""
struct jac_work { double *c, *ct, *share, *g; };

static int jac_alloc(long nd, struct jac_work *w) {
  long ng = NG > NGT ? NG : NGT;
  double *buf = malloc(sizeof(double) * (nd * (NV * NG + NGT) + (NV + 1 + ng) * CHUNK));
  if (!buf) return 2;
  w->c = buf; w->ct = w->c + nd * NV * NG; w->share = w->ct + nd * NGT; w->g = w->share + (NV + 1) * CHUNK;
  return 0;
}

/* One design over samples [0, n), p its parameter vector; w->c, w->ct set by jac_seeds. */
static void one_design_jac(long n, const double *theta, const double *omega, const double *omegadot,
                           const double *p, long nd, struct jac_work *w, double *out, long ld) {
  double arg[2 * NV];
  const double *ain[NP];
  double *aout[2 * NV];
  for (int q = 0; q < NP; ++q) ain[q] = p + q;
  for (int q = 0; q < 2 * NV; ++q) aout[q] = arg + q;
  loop_arguments_shared(1, ain, aout);
  const double *vin[5 + NP], *tin[1 + NV + NP], *rin[1 + NV + NP];
  double *vout[1 + NG], *rout[1 + NGT];
  for (int q = 0; q < NP; ++q) vin[5 + q] = tin[1 + NV + q] = rin[1 + NV + q] = p + q;
  for (long lo = 0; lo < n; lo += CHUNK) {
    long m = n - lo < CHUNK ? n - lo : CHUNK;
$shared_body  }
}

int pumpsim_simd_jac_blocks(long n, const double *theta, const double *omega, const double *omegadot,
                            const double *p, long block, long nd, const double *seed, double *out, long ld) {
  struct jac_work w;
  if (n < 0 || block < 1 || nd < 0 || ld < n) return 1;
  if (jac_alloc(nd, &w)) return 2;
  jac_seeds(nd, seed, w.c, w.ct);
  for (long b = 0; b * block < n; ++b) {
    long lo = b * block, m = n - lo < block ? n - lo : block;
    one_design_jac(m, theta + lo, omega + lo, omegadot + lo, p + b * NP, nd, &w, out + lo, ld);
  }
  free(w.c);
  return 0;
}

int pumpsim_simd_jac_samples(long n, const double *theta, const double *omega, const double *omegadot,
                             const double *pt, long pld, long nd, const double *seed, double *out, long ld) {
  struct jac_work ws, *w = &ws;
  if (n < 0 || pld < n || nd < 0 || ld < n) return 1;
  if (jac_alloc(nd, w)) return 2;
  jac_seeds(nd, seed, w->c, w->ct);
  double (*arg)[CHUNK] = malloc(sizeof(double) * 2 * NV * CHUNK);
  if (!arg) { free(w->c); return 2; }
  const double *ain[NP], *vin[5 + NP], *tin[1 + NV + NP], *rin[1 + NV + NP];
  double *aout[2 * NV], *vout[1 + NG], *rout[1 + NGT];
  for (int q = 0; q < 2 * NV; ++q) aout[q] = arg[q];
  for (long lo = 0; lo < n; lo += CHUNK) {
    long m = n - lo < CHUNK ? n - lo : CHUNK;
    for (int q = 0; q < NP; ++q) ain[q] = vin[5 + q] = tin[1 + NV + q] = rin[1 + NV + q] = pt + q * pld + lo;
    loop_arguments_samples(m, ain, aout);
$samples_body  }
  free(arg);
  free(w->c);
  return 0;
}
""")


def _rotor_gradient(torque: ca.Function):
    """The rotor's own terms' gradient (omegadot and p; the shares enter with weight 1, checked)."""
    ones = constant_jacobian(torque, 1)
    if any(abs(v - 1.0) > 0 for row in ones for v in row):
        raise CodegenError("the SIMD Jacobian needs the rotor torque to be the plain sum of the vane shares")
    rotor, cols = gradient_function(torque, "torque", [0, 2], "rotor_grad")
    return rotor, cols


def jacobian_source(fns: dict) -> tuple[str, dict]:
    """C text of the Jacobian entries for codegen/simd.py's functions `fns` (simd_functions; the
    library's loop_arguments_* and loop_torque_* are reused), and its manifest entries."""
    vane, args, torque = fns["vane"], fns["arguments"], fns["torque"]
    share = fns["outputs"][1 + fns["share_index"]]
    inputs = [i for i in range(vane.n_in()) if vane.name_in(i) not in LITERAL_INPUTS]  # not pz_one
    vgrad, vcols = gradient_function(vane, share, inputs, "vane_grad")
    rgrad, rcols = _rotor_gradient(torque)
    arg_jac = constant_jacobian(args, 0)
    n_in = vgrad.n_in()
    chunk = string.Template(_CHUNK_BODY)
    shared = chunk.substitute(mode="shared", args="vin[3] = arg + k; vin[4] = arg + NV + k;")
    samples = chunk.substitute(mode="samples", args="vin[3] = arg[k]; vin[4] = arg[NV + k];")
    parts = [
        emit_loop(vgrad, "loop_vane_grad_shared", {0, 1, 2}),
        emit_loop(vgrad, "loop_vane_grad_samples", set(range(n_in))),
        emit_loop(rgrad, "loop_rotor_grad_shared", {0, 1}),
        emit_loop(rgrad, "loop_rotor_grad_samples", {0, 1, 2}),
        _JAC.substitute(ng=len(vcols), ngt=len(rcols), vane_cols=_c_ints(vcols), rotor_cols=_c_ints(rcols),
                        arg_jac=_c_table(arg_jac), phi=_PHI, factor=_FACTOR, p=_P,
                        drivers=_DRIVERS.substitute(shared_body=shared, samples_body=samples)),
    ]
    info = {"seed_inputs": ["theta", "omega", "omegadot", "p"], "vane_gradient_rows": len(vcols),
            "vane_gradient_instructions": vgrad.n_instructions()}
    return "\n".join(parts), info
