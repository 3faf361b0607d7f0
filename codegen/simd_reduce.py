"""C text of the SIMD library's design-study entry (codegen/simd.py): each design's revolution is
evaluated into a scratch block that stays in cache and reduced there to the few numbers a design
study keeps (pumpsim.design.outputs.reduce_batch), so no samples x outputs array comes back.

  pumpsim_simd_reduce_designs(designs, n, theta, omega, p, alike, consts, tol, res, nres): each
      design (a row of p, its speed omega, omegadot 0) over the n rotor angles theta it shares with
      the others; per design consts (c_visc, L, l_m, bearing torque), tol (position, paradox
      tolerances); res (designs, nres) gets REDUCTIONS then one friction power per vane.
      alike > 1 (a 1-vane library only): the vane stands for `alike` vanes spaced n / alike samples
      apart (pumpsim.design.alike): the rotor torque is the bearing torque plus its shifted shares.

The arithmetic is reduce_batch's operation for operation, so its numbers are NumPy's bit for bit
(tested): means are NumPy's pairwise sum (numpy/_core/src/umath/loops_utils.h.src) divided by n;
extremes are the first maximum (or NaN) in vane-major order, as argmax has it; no FMA contraction
in these functions (the library's -ffp-contract=fast would fuse a*b + c).
"""
from __future__ import annotations

import string

# the per-design numbers before the per-vane friction powers, in the order of res's columns
REDUCTIONS = ("mean_torque", "rms_torque", "ptp_torque", "tip_friction_power", "slot_friction_power",
              "friction_power", "max_normal_force", "min_normal_force", "max_slot_force", "max_tip_pv_force_speed",
              "min_extension", "max_extension", "paradox", "positions_converged", "min_s", "max_s")
# the vane outputs read, as R_<NAME> row indices among the vane outputs
READ = ("torque_share", "s", "sdot", "normal", "slot1", "slot2", "tip_slip", "mu_housing", "mu_slot",
        "n_consistent", "ambiguity", "position_residual")

_SOURCE = string.Template(r"""
$rows
#define NRED $nred
#pragma GCC push_options
#pragma GCC optimize ("fp-contract=off")
static double pz_pairwise(const double *a, long n) {
  if (n < 8) {
    double res = -0.0;
    for (long i = 0; i < n; ++i) res += a[i];
    return res;
  }
  if (n <= 128) {
    double r[8], res;
    long i;
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    for (i = 8; i < n - (n % 8); i += 8)
      for (int j = 0; j < 8; ++j) r[j] += a[i + j];
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += a[i];
    return res;
  }
  long n2 = n / 2;
  n2 -= n2 % 8;
  return pz_pairwise(a, n2) + pz_pairwise(a + n2, n - n2);
}

/* np.add.reduce over a contiguous axis: the identity 0 plus the pairwise sum */
static double pz_sum(const double *a, long n) { return 0.0 + pz_pairwise(a, n); }

/* running arg-extreme as argmax/argmin: the first NaN, else the first largest (smallest) */
static inline void pz_max(double x, double *best) {
  if (*best == *best && (x != x || x > *best)) *best = x;
}
static inline void pz_min(double x, double *best) {
  if (*best == *best && (x != x || x < *best)) *best = x;
}
/* np.maximum: NaN if either is */
static inline double pz_maximum(double a, double b) { return (a != a || a >= b) ? a : b; }

/* One design: rows (1 + NO NV, ld) of the library's outputs over n samples, tq (n) scratch. */
static void reduce_design(long n, const double *rows, long ld, long alike, const double *k, const double *tol,
                          double *tq, double *w, double *res) {
  const double c_visc = k[0], L = k[1], lm = k[2], bearing = k[3];
  const double *t = rows;
  if (alike > 1) {  /* torque = bearing + ((s0 + s1) + s2) + ... of the shares shifted by n / alike */
    const double *sh = rows + (1 + (long)R_TORQUE_SHARE * NV) * ld;
    long step = n / alike;
    for (long j = 0; j < n; ++j) tq[j] = sh[j];
    for (long a = 1; a < alike; ++a)
      for (long j = 0; j < n; ++j) tq[j] += sh[(j + a * step) % n];
    for (long j = 0; j < n; ++j) tq[j] = bearing + tq[j];
    t = tq;
  }
  res[0] = pz_sum(t, n) / (double)n;
  long hi = 0, lo = 0;
  for (long j = 0; j < n; ++j) w[j] = t[j] * t[j];
  res[1] = sqrt(pz_sum(w, n) / (double)n);
  for (long j = 1; j < n; ++j) {
    if (t[hi] == t[hi] && (t[j] != t[j] || t[j] > t[hi])) hi = j;
    if (t[lo] == t[lo] && (t[j] != t[j] || t[j] < t[lo])) lo = j;
  }
  res[2] = t[hi] - t[lo];
#define ROW(name, v) (rows + (1 + (long)R_##name * NV + (v)) * ld)
  /* the extremes start at vane 0's first sample */
  double nmax = ROW(NORMAL, 0)[0], pvmax = nmax * fabs(ROW(TIP_SLIP, 0)[0]), smin = ROW(S, 0)[0];
  double nmin = nmax, smax = smin, emin = smin + L - lm, emax = emin;
  double fmax = pz_maximum(fabs(ROW(SLOT1, 0)[0]), fabs(ROW(SLOT2, 0)[0]));
  double tip_v[NV], slot_v[NV];
  int paradox = 0, res_ok = 1;
  for (int v = 0; v < NV; ++v) {
    const double *s = ROW(S, v), *sd = ROW(SDOT, v), *N = ROW(NORMAL, v), *F1 = ROW(SLOT1, v),
                 *F2 = ROW(SLOT2, v), *vt = ROW(TIP_SLIP, v), *mh = ROW(MU_HOUSING, v), *mr = ROW(MU_SLOT, v),
                 *nc = ROW(N_CONSISTENT, v), *amb = ROW(AMBIGUITY, v), *pr = ROW(POSITION_RESIDUAL, v);
    for (long j = 0; j < n; ++j) w[j] = mh[j] * N[j] * vt[j] + c_visc * vt[j] * vt[j];
    tip_v[v] = pz_sum(w, n) / (double)n;
    for (long j = 0; j < n; ++j) w[j] = mr[j] * sd[j] * (fabs(F1[j]) + fabs(F2[j]));
    slot_v[v] = pz_sum(w, n) / (double)n;
    for (long j = 0; j < n; ++j) {
      double e = s[j] + L - lm;
      pz_max(N[j], &nmax); pz_min(N[j], &nmin);
      pz_max(pz_maximum(fabs(F1[j]), fabs(F2[j])), &fmax);
      pz_max(N[j] * fabs(vt[j]), &pvmax);
      pz_max(e, &emax); pz_min(e, &emin);
      pz_max(s[j], &smax); pz_min(s[j], &smin);
      paradox |= (nc[j] < 0.5) | (amb[j] > tol[1]);
      res_ok &= (pr[j] - pr[j] == 0.0) & !(pr[j] > tol[0]);
    }
  }
#undef ROW
  /* reduce_batch's per-vane means, each repeated for the alike vanes it stands for, then summed */
  long nv = NV * alike;
  for (long i = 0; i < nv; ++i) w[i] = tip_v[i / alike];
  res[3] = pz_sum(w, nv);
  for (long i = 0; i < nv; ++i) w[i] = slot_v[i / alike];
  res[4] = pz_sum(w, nv);
  res[5] = res[3] + res[4];
  res[6] = nmax; res[7] = nmin; res[8] = fmax; res[9] = pvmax; res[10] = emin; res[11] = emax;
  res[12] = paradox; res[13] = res_ok; res[14] = smin; res[15] = smax;
  for (long i = 0; i < nv; ++i) res[NRED + i] = tip_v[i / alike] + slot_v[i / alike];
}
#pragma GCC pop_options

int pumpsim_simd_reduce_designs(long designs, long n, const double *theta, const double *omega, const double *p,
                                long alike, const double *consts, const double *tol, double *res, long nres) {
  if (designs < 0 || n < 1 || alike < 1 || (alike > 1 && (NV != 1 || n % alike)) || nres < NRED + NV * alike)
    return 1;
  long rows = 1 + (long)NO * NV, wn = n > NV * alike ? n : NV * alike;
  double *buf = malloc(sizeof(double) * (rows * n + 3 * n + wn));
  if (!buf) return 2;
  double *tq = buf + rows * n, *om = tq + n, *od = om + n, *w = od + n;
  for (long j = 0; j < n; ++j) od[j] = 0.0;
  for (long d = 0; d < designs; ++d) {
    for (long j = 0; j < n; ++j) om[j] = omega[d];
    one_design(n, theta, om, od, p + d * NP, buf, n);
    reduce_design(n, buf, n, alike, consts + 4 * d, tol, tq, w, res + d * nres);
  }
  free(buf);
  return 0;
}
""")


def reduction_source(vane_outputs) -> tuple[str, dict]:
    """C text of the reduction entry for a library whose vane outputs are `vane_outputs` (in row
    order), and its manifest entry."""
    rows = "\n".join(f"#define R_{nm.upper()} {list(vane_outputs).index(nm)}" for nm in READ)
    src = _SOURCE.substitute(rows=rows, nred=len(REDUCTIONS))
    return "#include <stdlib.h>\n" + src, {"columns": list(REDUCTIONS), "consts": ["c_visc", "L", "lm", "bearing"],
                                            "tolerances": ["position", "paradox"]}
