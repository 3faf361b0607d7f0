"""The C source of the direct CVODES driver (cvodes_driver builds it at first use): the solver over
the kernels' C entry points, a drive (a time-dependent input), root finding, forward sensitivities
with jumps at switches of the right-hand side, and the leading-block dense linear solver."""

from .cvodes_vectors import VECTOR_OPS

SOURCE = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <time.h>
#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sundials/sundials_dense.h>
typedef long long ci;
typedef int (*fn_t)(const double **, double **, ci *, double *, int);
typedef struct { fn_t f; const double **arg; double **res; ci *iw; double *w; int slot; } call_t;
typedef struct {
  SUNContext ctx; void *cv; N_Vector y, atol; SUNMatrix A; SUNLinearSolver LS; int n;
  call_t rhs, jac; int nout; const ci *off; ci jnnz; const ci *jpos; const double *jbuf; double *jsave;
  long nrhs, njac, base[5]; char msg[512];
  /* switching functions: a kernel's output `gout` (state pieces at arg slots gslot[i] from y +
     goff[i]), then states y[gidx[j]]; |g| < gtouch counts as 0 */
  call_t g; int gn1, gns, gnslot; const ci *gslot, *goff, *gidx; double *gbuf, gtouch;
  /* a drive: p[dslot] linear in t + doff on the uniform grid k * dstep of dn values dv (beyond its
     ends the end intervals' lines); dnk grid indices dk (increasing) are stops of the solver */
  double *pbuf, dstep, doff; const double *dv, *dk; int dslot, dn, dnk;
  /* forward sensitivities along parameter directions pdir (ns x np, dense) */
  int ns, np; const double *pdir, *ph; N_Vector *yS; double *sy, *sfp, *sjac, *sf0, st; int sfresh; long nsrhs;
  const ci *srow, *scol;
  /* switches of the right-hand side at fixed angles of y[0] (a vane reversing in its slot): nev
     angles evt in [0, 2 pi), their band half-widths evw / |y[1]| (at most wmax); kpos: the
     next one above the angle */
  int nev; const double *evt, *evw; double wmax, *yb, *fa, *fb; long kpos, njumps;
  /* a table of the kernels' angle-only inputs over one turn of y[0]: tn nodes tt (0 .. 2 pi), tg
     values tv and theta-derivatives td per node; periodic cubic Hermite into tgb (and tdg) before
     every kernel call; tk: the last interval */
  int tn, tg; const double *tt, *tv, *td; double *tgb, *tdg; long tk;
  /* timing (drv_timing): wall seconds inside the right-hand side, the Jacobian (each with the
     table's interpolation) and drv_run */
  int timing; double wrhs, wjac, wrun;
  /* blk: the leading-block solver is attached; mzero: the Newton matrix was zeroed once */
  int blk, mzero;
} drv_t;

static double wall_now(void) {
  struct timespec ts; clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* timing on or off; times[3]: the seconds so far (rhs, Jacobian, drv_run) */
void drv_timing(drv_t *d, int on, double *times) {
  d->timing = on; times[0] = d->wrhs; times[1] = d->wjac; times[2] = d->wrun;
}

static const double TWO_PI = 6.283185307179586;

static double ev_angle(drv_t *d, long k) {
  long q = k >= 0 ? k / d->nev : -((-k + d->nev - 1) / d->nev);
  return d->evt[k - q * d->nev] + q * TWO_PI;
}

static double ev_width(drv_t *d, long k, double omega) {
  long q = k >= 0 ? k / d->nev : -((-k + d->nev - 1) / d->nev);
  double w = d->evw[k - q * d->nev] / fabs(omega);
  return w < d->wmax ? w : 0.0;  /* a wider band (slow turning) is resolved by the steps */
}

/* Y with its angle moved out of a switch's band (to the edge on its side) into d->yb: the
   sensitivities take the switch as a jump (sjump), not through the steep band */
static const double *band_edge(drv_t *d, const double *Y) {
  if (!d->nev) return Y;
  double up = ev_angle(d, d->kpos), lo = ev_angle(d, d->kpos - 1), th = Y[0];
  double wu = ev_width(d, d->kpos, Y[1]), wl = ev_width(d, d->kpos - 1, Y[1]);
  double edge = th;
  if (wu > 0 && up - th < wu) edge = up - wu;
  else if (wl > 0 && th - lo < wl) edge = lo + wl;
  if (edge == th) return Y;
  memcpy(d->yb, Y, d->n * sizeof(double)); d->yb[0] = edge;
  return d->yb;
}

static int sroot(sunrealtype t, N_Vector y, sunrealtype *g, void *u) {
  drv_t *d = (drv_t *)u; double th = N_VGetArrayPointer(y)[0];
  g[0] = th - ev_angle(d, d->kpos); g[1] = th - ev_angle(d, d->kpos - 1);
  return 0;
}

static void drive(drv_t *d, double t) {
  if (!d->dv) return;
  double s = (t + d->doff) / d->dstep;
  int i = (int)floor(s);
  if (i > d->dn - 2) i = d->dn - 2;
  if (i < 0) i = 0;
  double f = s - i;
  d->pbuf[d->dslot] = d->dv[i] * (1 - f) + d->dv[i + 1] * f;
}

void drv_drive(drv_t *d, double *pbuf, int slot, double step, int n, const double *v, int nk, const double *k) {
  d->pbuf = pbuf; d->dslot = slot; d->dstep = step; d->dn = n; d->dv = v; d->dnk = nk; d->dk = k; d->doff = 0.0;
}

/* the solver's time t is the drive's t + off (a run on a clock of its own) */
void drv_drive_offset(drv_t *d, double off) { d->doff = off; }

/* CVode to tout (CV_NORMAL). With stops in the drive, the steps end on the next one rather than
   stepping across it (the input's slope jumps there). A stop is always set once there are any
   (one left behind the solver's time makes SUNDIALS 6 refuse the next call): past the last, far
   away. */
static int advance(drv_t *d, double tout, sunrealtype *tr) {
  if (!d->dv || !d->dnk) return CVode(d->cv, tout, d->y, tr, CV_NORMAL);
  for (;;) {
    sunrealtype tc; CVodeGetCurrentTime(d->cv, &tc);
    double s = (tc + d->doff) / d->dstep + 1e-9;
    int lo = 0, hi = d->dnk;  /* the first stop past tc */
    while (lo < hi) { int mid = (lo + hi) / 2; if (d->dk[mid] <= s) lo = mid + 1; else hi = mid; }
    double b = lo < d->dnk ? d->dk[lo] * d->dstep - d->doff : 1e300;
    if (CVodeSetStopTime(d->cv, b)) return -98;
    int flag = CVode(d->cv, tout, d->y, tr, CV_NORMAL);
    if (flag != CV_TSTOP_RETURN) return flag;
    if (*tr >= tout) return CV_SUCCESS;
  }
}

static int groot(sunrealtype t, N_Vector y, sunrealtype *g, void *u) {
  drv_t *d = (drv_t *)u; double *Y = N_VGetArrayPointer(y);
  drive(d, t);
  for (int i = 0; i < d->gnslot; i++) d->g.arg[d->gslot[i]] = Y + d->goff[i];
  if (d->gn1 && d->g.f(d->g.arg, d->g.res, d->g.iw, d->g.w, 0)) return 1;
  for (int i = 0; i < d->gn1; i++) g[i] = d->gbuf[i];
  for (int j = 0; j < d->gns; j++) g[d->gn1 + j] = Y[d->gidx[j]];
  for (int i = 0; i < d->gn1 + d->gns; i++) if (fabs(g[i]) < d->gtouch) g[i] = 0.0;
  return 0;
}

int drv_roots(drv_t *d, fn_t f, const double **arg, double **res, ci *iw, double *w, int nslot,
              const ci *slot, const ci *off, int n1, double *buf, int ns, const ci *idx, double touch) {
  d->g = (call_t){f, arg, res, iw, w, 0}; d->gnslot = nslot; d->gslot = slot; d->goff = off;
  d->gn1 = n1; d->gbuf = buf; d->gns = ns; d->gidx = idx; d->gtouch = touch;
  return CVodeRootInit(d->cv, n1 + ns, groot);
}

/* the table at angle th into tgb, and d/dth into tdg when slope */
static void table(drv_t *d, double th, int slope) {
  if (!d->tn) return;
  double a = th - TWO_PI * floor(th / TWO_PI);
  long k = d->tk, lo = 0, hi = d->tn - 1;
  if (!(d->tt[k] <= a && a < d->tt[k + 1])) {  /* steps move little: the last interval or a search */
    while (hi - lo > 1) { long mid = (lo + hi) / 2; if (d->tt[mid] <= a) lo = mid; else hi = mid; }
    k = d->tk = lo;
  }
  double h = d->tt[k + 1] - d->tt[k], u = (a - d->tt[k]) / h, v = 1 - u;
  double h00 = (1 + 2 * u) * v * v, h10 = u * v * v * h, h01 = u * u * (3 - 2 * u), h11 = -u * u * v * h;
  const double *y0 = d->tv + k * d->tg, *y1 = y0 + d->tg, *m0 = d->td + k * d->tg, *m1 = m0 + d->tg;
  for (int i = 0; i < d->tg; i++) d->tgb[i] = h00 * y0[i] + h10 * m0[i] + h01 * y1[i] + h11 * m1[i];
  if (!slope) return;
  double e0 = 6 * u * (u - 1) / h, e1 = v * (1 - 3 * u), e2 = u * (3 * u - 2);
  for (int i = 0; i < d->tg; i++) d->tdg[i] = e0 * (y0[i] - y1[i]) + e1 * m0[i] + e2 * m1[i];
}

void drv_table(drv_t *d, int n, const double *t, const double *v, const double *dv, int ng, double *gbuf,
               double *dgbuf) {
  d->tn = n; d->tt = t; d->tv = v; d->td = dv; d->tg = ng; d->tgb = gbuf; d->tdg = dgbuf; d->tk = 0;
}

static int feval(drv_t *d, double t, double *Y, double *D) {
  drive(d, t);
  table(d, Y[0], 0);
  d->rhs.arg[d->rhs.slot] = Y;
  for (int k = 0; k < d->nout; k++) d->rhs.res[k] = d->off[k] < 0 ? NULL : D + d->off[k];
  return d->rhs.f(d->rhs.arg, d->rhs.res, d->rhs.iw, d->rhs.w, 0) ? 1 : 0;
}

static int rhs(sunrealtype t, N_Vector y, N_Vector yd, void *u) {
  drv_t *d = (drv_t *)u;
  d->nrhs++;
  if (!d->timing) return feval(d, t, N_VGetArrayPointer(y), N_VGetArrayPointer(yd));
  double w0 = wall_now();
  int f = feval(d, t, N_VGetArrayPointer(y), N_VGetArrayPointer(yd));
  d->wrhs += wall_now() - w0;
  return f;
}

/* s_i' = J s_i + df/dp pdir_i: J from the Jacobian kernel, df/dp pdir_i a forward difference of
   the right-hand side over the step ph[i]; both kept while (t, y) stays (the staggered corrector's
   iterations) */
static int sensrhs(int Ns, sunrealtype t, N_Vector y, N_Vector fy, N_Vector *yS, N_Vector *ySd, void *u,
                   N_Vector t1, N_Vector t2) {
  drv_t *d = (drv_t *)u; int n = d->n; double *Y = N_VGetArrayPointer(y), *F = N_VGetArrayPointer(fy);
  if (!d->sfresh || t != d->st || memcmp(Y, d->sy, n * sizeof(double))) {
    memcpy(d->sy, Y, n * sizeof(double));
    Y = (double *)band_edge(d, Y);
    drive(d, t);
    table(d, Y[0], 1);
    d->jac.arg[d->jac.slot] = Y;
    if (d->jac.f(d->jac.arg, d->jac.res, d->jac.iw, d->jac.w, 0)) return 1;
    memcpy(d->sjac, d->jbuf, d->jnnz * sizeof(double));
    if (feval(d, t, Y, d->sf0)) return 1;
    F = d->sf0;
    for (int i = 0; i < Ns; i++) {
      const double *dir = d->pdir + (long)i * d->np; double h = d->ph[i], *G = d->sfp + (long)i * n;
      int moves = 0;
      for (int k = 0; k < d->np; k++) moves |= dir[k] != 0.0;
      if (!moves) { memset(G, 0, n * sizeof(double)); continue; }  /* an initial-condition direction */
      for (int k = 0; k < d->np; k++) d->pbuf[k] += h * dir[k];
      int bad = feval(d, t, Y, G);
      for (int k = 0; k < d->np; k++) d->pbuf[k] -= h * dir[k];
      if (bad) return 1;
      for (int r = 0; r < n; r++) G[r] = (G[r] - F[r]) / h;
      d->nsrhs++;
    }
    d->st = t; d->sfresh = 1;
  }
  for (int i = 0; i < Ns; i++) {
    double *S = N_VGetArrayPointer(yS[i]), *D = N_VGetArrayPointer(ySd[i]);
    memcpy(D, d->sfp + (long)i * n, n * sizeof(double));
    for (ci k = 0; k < d->jnnz; k++) if (d->srow[k] >= 0) D[d->srow[k]] += d->sjac[k] * S[d->scol[k]];
  }
  return 0;
}

/* a switch crossed at the root just returned: s += (f(band edge after) - f(band edge before))
   s_angle / |omega| (the crossing time's shift by the parameter, -s_angle / omega, times the jump
   of f), added to the sensitivities where the solver stands (tcur, past the root) */
static int sjump(drv_t *d, double tr) {
  int found[2]; double tcur; CVodeGetRootInfo(d->cv, found);
  double *Y = N_VGetArrayPointer(d->y);
  long k = found[0] ? d->kpos : d->kpos - 1;
  d->kpos += found[0] ? 1 : -1;
  double w = ev_width(d, k, Y[1]), th = ev_angle(d, k);
  d->sfresh = 0;
  if (w <= 0) return 0;
  memcpy(d->yb, Y, d->n * sizeof(double));
  d->yb[0] = th + w; if (feval(d, tr, d->yb, d->fa)) return 1;
  d->yb[0] = th - w; if (feval(d, tr, d->yb, d->fb)) return 1;
  if (CVodeGetSens(d->cv, &tr, d->yS)) return 1;
  double *c = calloc(d->ns, sizeof(double));
  for (int i = 0; i < d->ns; i++) c[i] = N_VGetArrayPointer(d->yS[i])[0] / fabs(Y[1]);
  CVodeGetCurrentTime(d->cv, &tcur);
  if (CVodeGetSensDky(d->cv, tcur, 0, d->yS)) { free(c); return 1; }
  for (int i = 0; i < d->ns; i++) {
    double *S = N_VGetArrayPointer(d->yS[i]);
    for (int r = 0; r < d->n; r++) S[r] += (d->fa[r] - d->fb[r]) * c[i];
  }
  free(c);
  d->njumps++;
  return CVodeSensReInit(d->cv, CV_STAGGERED, d->yS) ? 1 : 0;
}

/* the switch angles (nev, sorted in [0, 2 pi)) and their band coefficients (half-width x |omega|),
   bands wider than wmax ignored; after drv_sens */
int drv_switches(drv_t *d, int nev, const double *evt, const double *evw, double wmax) {
  if (nev < 1) return 0;
  d->nev = nev; d->evt = evt; d->evw = evw; d->wmax = wmax;
  d->yb = calloc(d->n, sizeof(double)); d->fa = calloc(d->n, sizeof(double)); d->fb = calloc(d->n, sizeof(double));
  return CVodeRootInit(d->cv, 2, sroot);
}

/* ns sensitivities along the directions pdir (ns x np) of the parameter buffer (drv_drive's), the
   difference steps ph, absolute tolerances atol / pscale[i]; errcon: in the error test or not
   (the staggered corrector either way) */
int drv_sens(drv_t *d, int ns, int np, const double *pdir, const double *ph, const double *pscale, int errcon,
             double rtol, const ci *srow, const ci *scol) {
  d->ns = ns; d->np = np; d->pdir = pdir; d->ph = ph; d->srow = srow; d->scol = scol;
  d->yS = N_VCloneVectorArray(ns, d->y);
  d->sy = calloc(d->n, sizeof(double)); d->sf0 = calloc(d->n, sizeof(double)); d->sfp = calloc((long)ns * d->n, sizeof(double));
  d->sjac = calloc(d->jnnz, sizeof(double));
  N_Vector *aS = N_VCloneVectorArray(ns, d->y);
  for (int i = 0; i < ns; i++) {
    N_VConst(0.0, d->yS[i]); N_VScale(1.0 / pscale[i], d->atol, aS[i]);
  }
  int f = CVodeSensInit(d->cv, ns, CV_STAGGERED, sensrhs, d->yS);
  if (!f) f = CVodeSensSVtolerances(d->cv, rtol, aS);
  if (!f) f = CVodeSetSensErrCon(d->cv, errcon);
  N_VDestroyVectorArray(aS, ns);
  return f;
}

/* CVODES' Newton matrix M = I - gamma J, built from the Jacobian kernel's nonzeros (kept in jsave
   while CVODES reuses its Jacobian) in place of its own set-up, which copies and scales a saved
   dense J on every call: the same products and sums, a third of the set-up's cost */
static int linsys(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix M, sunbooleantype jok, sunbooleantype *jcur,
                  sunrealtype gamma, void *u, N_Vector t1, N_Vector t2, N_Vector t3) {
  drv_t *d = (drv_t *)u;
  *jcur = !jok;
  if (!jok) {
    double w0 = d->timing ? wall_now() : 0.0;
    drive(d, t);
    table(d, NV_Ith_S(y, 0), 1);
    d->jac.arg[d->jac.slot] = N_VGetArrayPointer(y);
    d->njac++;
    if (d->jac.f(d->jac.arg, d->jac.res, d->jac.iw, d->jac.w, 0)) return 1;
    if (d->timing) d->wjac += wall_now() - w0;
    memcpy(d->jsave, d->jbuf, d->jnnz * sizeof(double));
  }
  double *A = SM_DATA_D(M);  /* column-major, leading dimension n; jpos = col * n + row */
  /* the leading-block solver factors a copy: M keeps its zeros, and only the Jacobian's nonzeros
     and the diagonal are written again (zeroing all of M was a sixth of the set-up) */
  if (!d->blk || !d->mzero) { SUNMatZero(M); d->mzero = d->blk; }
  else for (long i = 0; i < d->n; i++) A[i * d->n + i] = 0.0;
  for (ci k = 0; k < d->jnnz; k++) if (d->jpos[k] >= 0) A[d->jpos[k]] = -gamma * d->jsave[k];
  for (long i = 0; i < d->n; i++) A[i * d->n + i] += 1.0;
  return 0;
}

""" + VECTOR_OPS + r"""#if SUNDIALS_VERSION_MAJOR < 7
static void quiet(int code, const char *mod, const char *fn, char *msg, void *u) {
  drv_t *d = (drv_t *)u; snprintf(d->msg, sizeof d->msg, "%s: %s", fn, msg);
}
#endif

const char *drv_message(drv_t *d) { return d->msg; }

drv_t *drv_new(int n, double rtol, const double *atol, int max_order, long max_steps, double max_step,
               fn_t f, const double **farg, double **fres, ci *fiw, double *fw, int fslot, int nout,
               const ci *off, fn_t j, const double **jarg, double **jres, ci *jiw, double *jw, int jslot,
               ci jnnz, const ci *jpos, const double *jbuf, int own_ops) {
  drv_t *d = calloc(1, sizeof(drv_t));
#if SUNDIALS_VERSION_MAJOR >= 7
  if (SUNContext_Create(SUN_COMM_NULL, &d->ctx)) return NULL;
#else
  if (SUNContext_Create(NULL, &d->ctx)) return NULL;
#endif
  d->n = n; d->nout = nout; d->off = off; d->jnnz = jnnz; d->jpos = jpos; d->jbuf = jbuf;
  d->jsave = calloc(jnnz > 0 ? jnnz : 1, sizeof(double));
  d->rhs = (call_t){f, farg, fres, fiw, fw, fslot}; d->jac = (call_t){j, jarg, jres, jiw, jw, jslot};
  d->y = N_VNew_Serial(n, d->ctx); d->atol = N_VNew_Serial(n, d->ctx);
  if (own_ops) { fast_ops(d->y); fast_ops(d->atol); }
  for (int i = 0; i < n; i++) { NV_Ith_S(d->y, i) = 0.0; NV_Ith_S(d->atol, i) = atol[i]; }
  d->cv = CVodeCreate(CV_BDF, d->ctx);
  if (!d->cv || CVodeInit(d->cv, rhs, 0.0, d->y) || CVodeSVtolerances(d->cv, rtol, d->atol)) return NULL;
  CVodeSetUserData(d->cv, d);
#if SUNDIALS_VERSION_MAJOR < 7
  CVodeSetErrHandlerFn(d->cv, quiet, d);
#endif
  d->A = SUNDenseMatrix(n, n, d->ctx); d->LS = SUNLinSol_Dense(d->y, d->A, d->ctx);
  if (CVodeSetLinearSolver(d->cv, d->LS, d->A) || CVodeSetLinSysFn(d->cv, linsys)) return NULL;
  CVodeSetMaxOrd(d->cv, max_order); CVodeSetMaxNumSteps(d->cv, max_steps);
  if (max_step > 0) CVodeSetMaxStep(d->cv, max_step);
  return d;
}

static void counters(drv_t *d, long *c) {
  CVodeGetNumSteps(d->cv, c); CVodeGetNumLinSolvSetups(d->cv, c + 1); CVodeGetNumErrTestFails(d->cv, c + 2);
  CVodeGetNumNonlinSolvIters(d->cv, c + 3); CVodeGetNumNonlinSolvConvFails(d->cv, c + 4);
}

/* stats: steps, rhs, Jacobians, set-ups, error-test failures, Newton iterations, Newton failures,
   the sensitivities' right-hand-side differences */
static void stats_of(drv_t *d, long *st) {
  long c[5]; counters(d, c);
  st[0] = d->base[0] + c[0]; st[1] = d->nrhs; st[2] = d->njac;
  for (int i = 1; i < 5; i++) st[i + 2] = d->base[i] + c[i];
  st[7] = d->nsrhs; st[8] = d->njumps;
}

/* Y at tout[0..m); on a root (flag CV_ROOT_RETURN) it stops there: *done full rows, the root's
   time and state in *troot and yroot, which functions in found */
int drv_run(drv_t *d, double t0, const double *y0, int resume, int m, const double *tout, double *Y,
            long *st, int *done, double *troot, double *yroot, int *found, const double *yS0, double *SY) {
  int flag = 0; sunrealtype tr;
  double w0 = d->timing ? wall_now() : 0.0;
  d->msg[0] = 0; *done = 0;
  if (!resume) {
    long c[5]; counters(d, c);
    for (int i = 0; i < 5; i++) d->base[i] += c[i];
    memcpy(N_VGetArrayPointer(d->y), y0, d->n * sizeof(double));
    flag = CVodeReInit(d->cv, t0, d->y);
    if (!flag && d->ns) {
      for (int i = 0; i < d->ns; i++) memcpy(N_VGetArrayPointer(d->yS[i]), yS0 + (long)i * d->n, d->n * sizeof(double));
      d->sfresh = 0;
      flag = CVodeSensReInit(d->cv, CV_STAGGERED, d->yS);
    }
    if (d->nev) {  /* the first switch above the start angle */
      d->kpos = (long)floor(y0[0] / TWO_PI) * d->nev;
      while (ev_angle(d, d->kpos) <= y0[0]) d->kpos++;
      while (ev_angle(d, d->kpos - 1) > y0[0]) d->kpos--;
    }
  }
  for (int k = 0; k < m && flag >= 0; k++) {
    flag = advance(d, tout[k], &tr);
    if (flag == CV_ROOT_RETURN && d->nev) {
      if (sjump(d, tr)) { flag = -99; snprintf(d->msg, sizeof d->msg, "a sensitivity jump failed"); break; }
      k--;
      continue;
    }
    if (flag == CV_ROOT_RETURN) {
      *troot = tr; memcpy(yroot, N_VGetArrayPointer(d->y), d->n * sizeof(double));
      CVodeGetRootInfo(d->cv, found); break;
    }
    if (flag >= 0) {
      memcpy(Y + (long)k * d->n, N_VGetArrayPointer(d->y), d->n * sizeof(double)); *done = k + 1;
      if (d->ns) {
        CVodeGetSens(d->cv, &tr, d->yS);
        for (int i = 0; i < d->ns; i++)
          memcpy(SY + ((long)k * d->ns + i) * d->n, N_VGetArrayPointer(d->yS[i]), d->n * sizeof(double));
      }
    }
    else { double h; CVodeGetCurrentTime(d->cv, &h); snprintf(d->msg + strlen(d->msg), 64, " (t = %.9g)", h); }
  }
  stats_of(d, st);
  if (d->timing) d->wrun += wall_now() - w0;
  return flag;
}

/* Leading-block dense solver: the Newton matrix I - gamma J of a system whose rows from nl on
   have a zero Jacobian (quadratures riding along as states) is [[M11, 0], [0, I]]; only M11 is
   factored and solved, with the dense solver's own LU, so the results are those of the full LU
   (its extra rows and columns only add zeros) at a fraction of the cost. */
/* LU with partial pivoting (column-major a, n x n) and its solve: the dense solver's algorithm,
   operation for operation, on contiguous columns the compiler can vectorise (SUNDIALS' own goes
   through column pointers: ~3 us a factorisation and ~0.7 us a solve at n = 16) */
static sunindextype lu_factor(double *a, sunindextype n, sunindextype *p) {
  for (sunindextype k = 0; k < n; k++) {
    double *ck = a + k * n;
    sunindextype l = k;
    for (sunindextype i = k + 1; i < n; i++) if (fabs(ck[i]) > fabs(ck[l])) l = i;
    p[k] = l;
    if (ck[l] == 0.0) return k + 1;
    if (l != k)
      for (sunindextype j = 0; j < n; j++) { double t = a[j * n + l]; a[j * n + l] = a[j * n + k]; a[j * n + k] = t; }
    double mult = 1.0 / ck[k];
    for (sunindextype i = k + 1; i < n; i++) ck[i] *= mult;
    for (sunindextype j = k + 1; j < n; j++) {
      double *cj = a + j * n, akj = cj[k];
      if (akj != 0.0)
        for (sunindextype i = k + 1; i < n; i++) cj[i] -= akj * ck[i];
    }
  }
  return 0;
}

static void lu_solve(const double *a, sunindextype n, const sunindextype *p, double *b) {
  for (sunindextype k = 0; k < n; k++)
    if (p[k] != k) { double t = b[k]; b[k] = b[p[k]]; b[p[k]] = t; }
  for (sunindextype k = 0; k < n - 1; k++)
    for (sunindextype i = k + 1; i < n; i++) b[i] -= a[k * n + i] * b[k];
  for (sunindextype k = n - 1; k > 0; k--) {
    b[k] /= a[k * n + k];
    for (sunindextype i = 0; i < k; i++) b[i] -= a[k * n + i] * b[k];
  }
  b[0] /= a[0];
}

typedef struct { sunindextype nl; SUNMatrix B; sunindextype *piv; } blk_t;
static SUNLinearSolver_Type blk_type(SUNLinearSolver S) { return SUNLINEARSOLVER_DIRECT; }
static SUNLinearSolver_ID blk_id(SUNLinearSolver S) { return SUNLINEARSOLVER_CUSTOM; }
static int blk_init(SUNLinearSolver S) { return 0; }
static int blk_setup(SUNLinearSolver S, SUNMatrix A) {
  blk_t *b = (blk_t *)S->content; sunindextype nl = b->nl, n = SM_ROWS_D(A);
  for (sunindextype j = 0; j < nl; j++) memcpy(SM_COLUMN_D(b->B, j), SM_DATA_D(A) + j * n, nl * sizeof(double));
#ifdef SUNLS_LUFACT_FAIL
  return lu_factor(SM_DATA_D(b->B), nl, b->piv) > 0 ? SUNLS_LUFACT_FAIL : 0;
#else
  return lu_factor(SM_DATA_D(b->B), nl, b->piv) > 0 ? 1 : 0;
#endif
}
static int blk_solve(SUNLinearSolver S, SUNMatrix A, N_Vector x, N_Vector r, sunrealtype tol) {
  blk_t *b = (blk_t *)S->content;
  N_VScale(1.0, r, x);
  lu_solve(SM_DATA_D(b->B), b->nl, b->piv, N_VGetArrayPointer(x));
  return 0;
}
static int blk_free(SUNLinearSolver S) {
  if (!S) return 0;
  blk_t *b = (blk_t *)S->content;
  if (b) { SUNMatDestroy(b->B); free(b->piv); free(b); }
  S->content = NULL; SUNLinSolFreeEmpty(S);
  return 0;
}

/* solve the Newton systems on the leading nl x nl block only (rows nl.. of the Jacobian zero);
   before drv_tune: attaching a linear solver resets CVODES' Jacobian settings */
int drv_block_solver(drv_t *d, int nl) {
  SUNLinearSolver S = SUNLinSolNewEmpty(d->ctx);
  if (!S) return -1;
  blk_t *b = calloc(1, sizeof(blk_t));
  S->content = b; S->ops->gettype = blk_type; S->ops->getid = blk_id; S->ops->initialize = blk_init;
  S->ops->setup = blk_setup; S->ops->solve = blk_solve; S->ops->free = blk_free;
  b->nl = nl; b->B = SUNDenseMatrix(nl, nl, d->ctx); b->piv = malloc(nl * sizeof(sunindextype));
  if (!b->B || !b->piv || CVodeSetLinearSolver(d->cv, S, d->A) || CVodeSetLinSysFn(d->cv, linsys)) {
    blk_free(S); return -1;
  }
  SUNLinSolFree(d->LS); d->LS = S; d->blk = 1; d->mzero = 0;
  return 0;
}

/* Newton iterations per step, steps between Jacobian updates, Newton convergence coefficient
   (0: CVODES' default) */
int drv_tune(drv_t *d, int maxcor, long msbj, double nlscoef) {
  int f = 0;
  if (maxcor > 0) f |= CVodeSetMaxNonlinIters(d->cv, maxcor);
  if (msbj > 0) f |= CVodeSetJacEvalFrequency(d->cv, msbj);
  if (nlscoef > 0) f |= CVodeSetNonlinConvCoef(d->cv, nlscoef);
  return f;
}

/* the band of step-size ratios that leave the step unchanged after a successful step (CVODES'
   default [0, 1.5]: a step is never shrunk before it fails) */
int drv_step_bounds(drv_t *d, double lo, double hi) { return CVodeSetEtaFixedStepBounds(d->cv, lo, hi); }

/* one step at a time from (t0, y0) until tend (the last step may pass it), at most maxrec steps;
   per step in rec (stride 6 + n): t, h, order, y[0], the error-test and Newton failures since the
   step before, then the local error estimate times the error weight per component (its rms is
   the error test's norm, 1 at the tolerance) */
int drv_profile(drv_t *d, double t0, const double *y0, double tend, long maxrec, double *rec, long *nrec) {
  int n = d->n, flag;
  long k = 0, c[5], prev[5];
  sunrealtype t = t0, h; int q;
  N_Vector ele = N_VClone(d->y), ewt = N_VClone(d->y);
  memcpy(N_VGetArrayPointer(d->y), y0, n * sizeof(double));
  counters(d, c);
  for (int i = 0; i < 5; i++) d->base[i] += c[i];
  flag = CVodeReInit(d->cv, t0, d->y);
  if (!flag && d->dv && d->dnk) flag = CVodeSetStopTime(d->cv, 1e300);  /* no drive stops here */
  counters(d, prev);
  while (!flag && t < tend && k < maxrec) {
    flag = CVode(d->cv, tend, d->y, &t, CV_ONE_STEP);
    if (flag < 0) break;
    flag = 0;
    double *r = rec + k * (6 + n);
    counters(d, c); CVodeGetLastStep(d->cv, &h); CVodeGetLastOrder(d->cv, &q);
    CVodeGetEstLocalErrors(d->cv, ele); CVodeGetErrWeights(d->cv, ewt);
    r[0] = t; r[1] = h; r[2] = q; r[3] = NV_Ith_S(d->y, 0); r[4] = c[2] - prev[2]; r[5] = c[4] - prev[4];
    for (int i = 0; i < n; i++) r[6 + i] = NV_Ith_S(ele, i) * NV_Ith_S(ewt, i);
    memcpy(prev, c, sizeof c); k++;
  }
  *nrec = k; N_VDestroy(ele); N_VDestroy(ewt);
  return flag;
}

/* a kernel over the rows of X (nrow x nx, row-major) in one call: row r at arg[slot], output k
   written at out[k] + r size[k] (out[k] NULL: not wanted) */
int drv_rows(fn_t f, const double **arg, double **res, ci *iw, double *w, int slot, long nrow, const double *X,
             long nx, int nout, double **out, const ci *size) {
  for (long r = 0; r < nrow; r++) {
    arg[slot] = X + r * nx;
    for (int k = 0; k < nout; k++) res[k] = out[k] ? out[k] + r * size[k] : NULL;
    if (f(arg, res, iw, w, 0)) return 1;
  }
  return 0;
}

void drv_free(drv_t *d) {
  if (!d) return;
  if (d->ns) { N_VDestroyVectorArray(d->yS, d->ns); free(d->sy); free(d->sf0); free(d->sfp); free(d->sjac); }
  if (d->nev) { free(d->yb); free(d->fa); free(d->fb); }
  CVodeFree(&d->cv); SUNLinSolFree(d->LS); SUNMatDestroy(d->A); N_VDestroy(d->y); N_VDestroy(d->atol);
  SUNContext_Free(&d->ctx); free(d->jsave); free(d);
}
"""
