"""CVODES driven directly over the compiled kernels, without CasADi's integrator layer.

CasADi's CVODES plugin re-initialises the solver on every call (each output chunk starts again at
order 1 with a tiny step), evaluates the Jacobian at nearly every linear-solver set-up and adds its
own per-step work. This driver is a small C library over the system's SUNDIALS: CVODES' own dense
linear solver (so the Jacobian is reused as CVODES decides), a vector absolute tolerance, and one
solver memory that carries on from one output chunk to the next when the caller continues from
where the last call ended (`resume`). The right-hand side and its Jacobian are the kernels' own
compiled functions, called through their C entry points.

A fresh machine needs a C compiler (as for the kernels) and the SUNDIALS 6 or 7 headers and
libraries (Debian/Ubuntu 24.04: `apt-get install libsundials-dev`; conda: `sundials`; Homebrew:
`sundials`). The library is built once into the kernel folder; where it cannot be built or
loaded, `available()` says why and the callers use CasADi's CVODES plugin instead (same
equations, same tolerances). PUMPSIM_CVODES=casadi forces that path.
"""
from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import subprocess

import numpy as np

from .errors import SolverError

ENV = "PUMPSIM_CVODES"
LIBS = ["-lsundials_cvodes", "-lsundials_nvecserial", "-lsundials_sunmatrixdense",
        "-lsundials_sunlinsoldense", "-lm"]
SOURCE = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
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
  call_t rhs, jac; int nout; const ci *off; ci jnnz; const ci *jpos; const double *jbuf;
  long nrhs, njac, base[5]; char msg[512];
  /* switching functions: a kernel's output `gout` (state pieces at arg slots gslot[i] from y +
     goff[i]), then states y[gidx[j]]; |g| < gtouch counts as 0 */
  call_t g; int gn1, gns, gnslot; const ci *gslot, *goff, *gidx; double *gbuf, gtouch;
  /* a drive: p[dslot] linear in t on the uniform grid k * dstep of dn values dv */
  double *pbuf, dstep; const double *dv; int dslot, dn;
  /* forward sensitivities along parameter directions pdir (ns x np, dense) */
  int ns, np; const double *pdir, *ph; N_Vector *yS; double *sy, *sfp, *sjac, *sf0, st; int sfresh; long nsrhs;
  const ci *srow, *scol;
  /* switches of the right-hand side at fixed angles of y[0] (a vane reversing in its slot): nev
     angles evt in [0, 2 pi), their band half-widths evw / |y[1]| (at most wmax); kpos: the
     next one above the angle */
  int nev; const double *evt, *evw; double wmax, *yb, *fa, *fb; long kpos, njumps;
} drv_t;

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
  int i = (int)floor(t / d->dstep);
  if (i > d->dn - 2) i = d->dn - 2;
  if (i < 0) i = 0;
  double f = t / d->dstep - i;
  d->pbuf[d->dslot] = d->dv[i] * (1 - f) + d->dv[i + 1] * f;
}

void drv_drive(drv_t *d, double *pbuf, int slot, double step, int n, const double *v) {
  d->pbuf = pbuf; d->dslot = slot; d->dstep = step; d->dn = n; d->dv = v;
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

static int feval(drv_t *d, double t, double *Y, double *D) {
  drive(d, t);
  d->rhs.arg[d->rhs.slot] = Y;
  for (int k = 0; k < d->nout; k++) d->rhs.res[k] = d->off[k] < 0 ? NULL : D + d->off[k];
  return d->rhs.f(d->rhs.arg, d->rhs.res, d->rhs.iw, d->rhs.w, 0) ? 1 : 0;
}

static int rhs(sunrealtype t, N_Vector y, N_Vector yd, void *u) {
  drv_t *d = (drv_t *)u;
  d->nrhs++;
  return feval(d, t, N_VGetArrayPointer(y), N_VGetArrayPointer(yd));
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
    d->jac.arg[d->jac.slot] = Y;
    if (d->jac.f(d->jac.arg, d->jac.res, d->jac.iw, d->jac.w, 0)) return 1;
    memcpy(d->sjac, d->jbuf, d->jnnz * sizeof(double));
    if (feval(d, t, Y, d->sf0)) return 1;
    F = d->sf0;
    for (int i = 0; i < Ns; i++) {
      const double *dir = d->pdir + (long)i * d->np; double h = d->ph[i], *G = d->sfp + (long)i * n;
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
  N_Vector *aS = N_VCloneVectorArray(ns, d->y); double *as = calloc(ns, sizeof(double));
  for (int i = 0; i < ns; i++) {
    N_VConst(0.0, d->yS[i]); N_VScale(1.0 / pscale[i], d->atol, aS[i]);
  }
  int f = CVodeSensInit(d->cv, ns, CV_STAGGERED, sensrhs, d->yS);
  if (!f) f = CVodeSensSVtolerances(d->cv, rtol, aS);
  if (!f) f = CVodeSetSensErrCon(d->cv, errcon);
  N_VDestroyVectorArray(aS, ns); free(as);
  return f;
}

static int jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *u, N_Vector t1,
               N_Vector t2, N_Vector t3) {
  drv_t *d = (drv_t *)u;
  drive(d, t);
  d->jac.arg[d->jac.slot] = N_VGetArrayPointer(y);
  d->njac++;
  if (d->jac.f(d->jac.arg, d->jac.res, d->jac.iw, d->jac.w, 0)) return 1;
  SUNMatZero(J);
  double *A = SM_DATA_D(J);  /* column-major, leading dimension n; jpos = col * n + row */
  for (ci k = 0; k < d->jnnz; k++) if (d->jpos[k] >= 0) A[d->jpos[k]] = d->jbuf[k];
  return 0;
}

#if SUNDIALS_VERSION_MAJOR < 7
static void quiet(int code, const char *mod, const char *fn, char *msg, void *u) {
  drv_t *d = (drv_t *)u; snprintf(d->msg, sizeof d->msg, "%s: %s", fn, msg);
}
#endif

const char *drv_message(drv_t *d) { return d->msg; }

drv_t *drv_new(int n, double rtol, const double *atol, int max_order, long max_steps, double max_step,
               fn_t f, const double **farg, double **fres, ci *fiw, double *fw, int fslot, int nout,
               const ci *off, fn_t j, const double **jarg, double **jres, ci *jiw, double *jw, int jslot,
               ci jnnz, const ci *jpos, const double *jbuf) {
  drv_t *d = calloc(1, sizeof(drv_t));
#if SUNDIALS_VERSION_MAJOR >= 7
  if (SUNContext_Create(SUN_COMM_NULL, &d->ctx)) return NULL;
#else
  if (SUNContext_Create(NULL, &d->ctx)) return NULL;
#endif
  d->n = n; d->nout = nout; d->off = off; d->jnnz = jnnz; d->jpos = jpos; d->jbuf = jbuf;
  d->rhs = (call_t){f, farg, fres, fiw, fw, fslot}; d->jac = (call_t){j, jarg, jres, jiw, jw, jslot};
  d->y = N_VNew_Serial(n, d->ctx); d->atol = N_VNew_Serial(n, d->ctx);
  for (int i = 0; i < n; i++) { NV_Ith_S(d->y, i) = 0.0; NV_Ith_S(d->atol, i) = atol[i]; }
  d->cv = CVodeCreate(CV_BDF, d->ctx);
  if (!d->cv || CVodeInit(d->cv, rhs, 0.0, d->y) || CVodeSVtolerances(d->cv, rtol, d->atol)) return NULL;
  CVodeSetUserData(d->cv, d);
#if SUNDIALS_VERSION_MAJOR < 7
  CVodeSetErrHandlerFn(d->cv, quiet, d);
#endif
  d->A = SUNDenseMatrix(n, n, d->ctx); d->LS = SUNLinSol_Dense(d->y, d->A, d->ctx);
  if (CVodeSetLinearSolver(d->cv, d->LS, d->A) || CVodeSetJacFn(d->cv, jac)) return NULL;
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
    flag = CVode(d->cv, tout[k], d->y, &tr, CV_NORMAL);
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
  return flag;
}

/* Leading-block dense solver: the Newton matrix I - gamma J of a system whose rows from nl on
   have a zero Jacobian (quadratures riding along as states) is [[M11, 0], [0, I]]; only M11 is
   factored and solved, with the dense solver's own LU, so the results are those of the full LU
   (its extra rows and columns only add zeros) at a fraction of the cost. */
typedef struct { sunindextype nl; SUNMatrix B; sunindextype *piv; } blk_t;
static SUNLinearSolver_Type blk_type(SUNLinearSolver S) { return SUNLINEARSOLVER_DIRECT; }
static SUNLinearSolver_ID blk_id(SUNLinearSolver S) { return SUNLINEARSOLVER_CUSTOM; }
static int blk_init(SUNLinearSolver S) { return 0; }
static int blk_setup(SUNLinearSolver S, SUNMatrix A) {
  blk_t *b = (blk_t *)S->content; sunindextype nl = b->nl, n = SM_ROWS_D(A);
  for (sunindextype j = 0; j < nl; j++) memcpy(SM_COLUMN_D(b->B, j), SM_DATA_D(A) + j * n, nl * sizeof(double));
#ifdef SUNLS_LUFACT_FAIL
  return SUNDlsMat_denseGETRF(SM_COLS_D(b->B), nl, nl, b->piv) > 0 ? SUNLS_LUFACT_FAIL : 0;
#else
  return SUNDlsMat_denseGETRF(SM_COLS_D(b->B), nl, nl, b->piv) > 0 ? 1 : 0;
#endif
}
static int blk_solve(SUNLinearSolver S, SUNMatrix A, N_Vector x, N_Vector r, sunrealtype tol) {
  blk_t *b = (blk_t *)S->content;
  N_VScale(1.0, r, x);
  SUNDlsMat_denseGETRS(SM_COLS_D(b->B), b->nl, b->piv, N_VGetArrayPointer(x));
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
  if (!b->B || !b->piv || CVodeSetLinearSolver(d->cv, S, d->A) || CVodeSetJacFn(d->cv, jac)) {
    blk_free(S); return -1;
  }
  SUNLinSolFree(d->LS); d->LS = S;
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

void drv_free(drv_t *d) {
  if (!d) return;
  if (d->ns) { N_VDestroyVectorArray(d->yS, d->ns); free(d->sy); free(d->sf0); free(d->sfp); free(d->sjac); }
  if (d->nev) { free(d->yb); free(d->fa); free(d->fb); }
  CVodeFree(&d->cv); SUNLinSolFree(d->LS); SUNMatDestroy(d->A); N_VDestroy(d->y); N_VDestroy(d->atol);
  SUNContext_Free(&d->ctx); free(d);
}
"""
STAT_NAMES = ("nsteps", "nfevals", "njevals", "nlinsetups", "netfails", "nniters", "nncfails", "nsens_fevals", "njumps")
_LIB: dict = {}


def _build() -> ctypes.CDLL:
    from .model_spec import manifest as mf

    tag = hashlib.sha1((SOURCE + " ".join(LIBS)).encode()).hexdigest()[:16]
    folder = mf.generated_dir() / f"cvodes-driver-{tag}"
    lib = folder / "pumpsim_cvodes.so"
    if not lib.exists():
        folder.mkdir(parents=True, exist_ok=True)
        src = folder / f"pumpsim_cvodes.{os.getpid()}.c"  # per process: builds may run side by side
        src.write_text(SOURCE)
        tmp = folder / f".{os.getpid()}.so"
        cc = os.environ.get("CC", "cc")
        try:
            out = subprocess.run([cc, "-O2", "-fPIC", "-shared", str(src), "-o", str(tmp), *LIBS],
                                 capture_output=True, text=True)
        finally:
            src.unlink()
        if out.returncode:
            raise OSError(f"{cc} could not build the CVODES driver (SUNDIALS headers or libraries missing?): "
                          + (out.stderr.strip().splitlines() or ["no message"])[-1])
        os.replace(tmp, lib)
        logging.getLogger("pumpsim").debug("built the direct CVODES driver in %s", folder)  # ~1 s: no notice
    dll = ctypes.CDLL(str(lib))
    p = ctypes.c_void_p
    dll.drv_new.restype = p
    dll.drv_new.argtypes = [ctypes.c_int, ctypes.c_double, p, ctypes.c_int, ctypes.c_long, ctypes.c_double,
                            p, p, p, p, p, ctypes.c_int, ctypes.c_int, p, p, p, p, p, p, ctypes.c_int,
                            ctypes.c_longlong, p, p]
    dll.drv_run.argtypes = [p, ctypes.c_double, p, ctypes.c_int, ctypes.c_int, p, p, p, p, p, p, p, p, p]
    dll.drv_drive.argtypes = [p, p, ctypes.c_int, ctypes.c_double, ctypes.c_int, p]
    dll.drv_switches.argtypes = [p, ctypes.c_int, p, p, ctypes.c_double]
    dll.drv_sens.argtypes = [p, ctypes.c_int, ctypes.c_int, p, p, p, ctypes.c_int, ctypes.c_double, p, p]
    dll.drv_roots.argtypes = [p, p, p, p, p, p, ctypes.c_int, p, p, ctypes.c_int, p, ctypes.c_int, p,
                              ctypes.c_double]
    dll.drv_message.restype = ctypes.c_char_p
    dll.drv_message.argtypes = [p]
    dll.drv_free.argtypes = [p]
    dll.drv_tune.argtypes = [p, ctypes.c_int, ctypes.c_long, ctypes.c_double]
    dll.drv_block_solver.argtypes = [p, ctypes.c_int]
    return dll


def library():
    """The driver library, or None (available() says why)."""
    if os.environ.get(ENV, "").lower() == "casadi":
        return None
    if "lib" not in _LIB:
        try:
            _LIB["lib"], _LIB["why"] = _build(), ""
        except (OSError, subprocess.SubprocessError) as e:
            _LIB["lib"], _LIB["why"] = None, str(e)
            logging.getLogger("pumpsim").debug("CVODES through CasADi's plugin: %s", e)
    return _LIB["lib"]


def available() -> tuple[bool, str]:
    """(usable, why not); checked at every solver set-up, so PUMPSIM_CVODES=casadi applies to
    the next run."""
    if library() is None:
        return False, _LIB.get("why") or f"{ENV}=casadi"
    return True, ""


def _ptr(a) -> int:
    return a.ctypes.data


class KernelCall:
    """One compiled kernel function `name` of the library at `so`: its work buffers, its inputs
    (fixed arrays, the state's slot filled per call) and outputs."""

    def __init__(self, so, name, inputs, state_slot):
        self.dll = ctypes.CDLL(str(so))
        self.fn = getattr(self.dll, name)
        sz = [ctypes.c_longlong() for _ in range(4)]
        getattr(self.dll, name + "_work")(*[ctypes.byref(s) for s in sz])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sz)
        self.keep = [np.ascontiguousarray(v, dtype=float) for v in inputs]
        self.arg = np.zeros(n_arg, dtype=np.uintp)
        for i, v in enumerate(self.keep):
            if i != state_slot:
                self.arg[i] = _ptr(v)
        self.res = np.zeros(n_res, dtype=np.uintp)
        self.iw = np.zeros(n_iw, dtype=np.int64)
        self.w = np.zeros(n_w)
        self.slot = state_slot

    def __call__(self, x, outs):
        """Evaluate at state x into the arrays outs (None: output not wanted); returns outs."""
        x = np.ascontiguousarray(x, dtype=float)
        self.arg[self.slot] = _ptr(x)
        for k, o in enumerate(outs):
            self.res[k] = 0 if o is None else _ptr(o)
        if self.fn(ctypes.c_void_p(_ptr(self.arg)), ctypes.c_void_p(_ptr(self.res)),
                   ctypes.c_void_p(_ptr(self.iw)), ctypes.c_void_p(_ptr(self.w)), 0):
            raise SolverError("a compiled kernel failed to evaluate")
        return outs

    def address(self) -> int:
        return ctypes.cast(self.fn, ctypes.c_void_p).value


class Driver:
    """CVODES (BDF, dense direct solver, CVODES' Jacobian reuse) on y' = f(y) of a kernel.

    rhs, jac: KernelCall of the right-hand side and its Jacobian; out_offsets: where each rhs
    output starts in y' (-1: not wanted); jac_blocks: per Jacobian output, (sparsity, row offset)
    or None (not wanted); atol: per component; jac_every: steps between Jacobian updates at
    most (CVODES' default 51); lin_size: the Jacobian's rows from lin_size on are zero (states
    that do not feed back, such as quadratures riding along): the Newton systems are then solved
    on the leading block only, with the same results."""

    def __init__(self, n, rhs, out_offsets, jac, jac_blocks, rtol, atol, max_order=5, max_steps=500000,
                 max_step=None, jac_every=None, lin_size=None):
        self.lib = library()
        if self.lib is None:
            raise OSError(available()[1])
        self.n = n
        self.rhs, self.jac = rhs, jac
        self.off = np.asarray(out_offsets, dtype=np.int64)
        bufs, pos = [], []
        for k, block in enumerate(jac_blocks):
            if block is None:
                continue
            sp, r0 = block
            rows, cols = sp.get_triplet()
            buf = np.zeros(len(rows))
            jac.res[k] = _ptr(buf)
            bufs.append(buf)
            pos.append(np.asarray(cols, dtype=np.int64) * n + np.asarray(rows, dtype=np.int64) + r0)
        self.jbuf = np.concatenate(bufs) if len(bufs) > 1 else bufs[0]
        if len(bufs) > 1:  # one buffer: the outputs write into consecutive parts of it
            start = 0
            for k, block in enumerate(jac_blocks):
                if block is not None:
                    jac.res[k] = _ptr(self.jbuf) + 8 * start
                    start += block[0].nnz()
        self.jpos = np.concatenate(pos)
        self.atol = np.ascontiguousarray(atol, dtype=float)
        self.rtol = float(rtol)
        self.stats_now = np.zeros(len(STAT_NAMES), dtype=np.int64)
        self.handle = self.lib.drv_new(
            n, float(rtol), _ptr(self.atol), int(max_order), int(max_steps), float(max_step or 0.0),
            rhs.address(), _ptr(rhs.arg), _ptr(rhs.res), _ptr(rhs.iw), _ptr(rhs.w), rhs.slot, self.off.size,
            _ptr(self.off), jac.address(), _ptr(jac.arg), _ptr(jac.res), _ptr(jac.iw), _ptr(jac.w), jac.slot,
            self.jpos.size, _ptr(self.jpos), _ptr(self.jbuf))
        if not self.handle:
            raise OSError("SUNDIALS could not set up CVODES")
        if lin_size is not None and lin_size < n and self.lib.drv_block_solver(self.handle, int(lin_size)):
            raise OSError("SUNDIALS could not set up the leading-block linear solver")
        if jac_every:
            self.lib.drv_tune(self.handle, 0, int(jac_every), 0.0)
        self.last = None  # (t, y) where the solver memory stands
        self.n_roots, self.root = 0, None
        self.n_sens, self.sensitivities = 0, None

    def set_drive(self, pbuf, slot, step, values):
        """A time-dependent input: before every kernel call pbuf[slot] (pbuf: the kernels' parameter
        array) becomes the linear interpolation at t of `values` on the grid 0, step, 2 step, ..."""
        self._drive = (pbuf, np.ascontiguousarray(values, dtype=float))
        self.lib.drv_drive(self.handle, _ptr(pbuf), int(slot), float(step), self._drive[1].size, _ptr(self._drive[1]))

    def set_sensitivities(self, directions, steps, scales, error_control=False):
        """Forward sensitivities of y along parameter directions (rows of `directions`, in the
        drive's parameter buffer, set_drive): s' = J s + df/dp d with J the Jacobian kernel's and
        df/dp d a forward difference of the right-hand side over `steps`; absolute tolerances
        atol / scales; error_control: the sensitivities in the error test (the staggered corrector
        either way). Before any run; `run` then also fills self.sensitivities (m, ns, n)."""
        D = np.ascontiguousarray(directions, dtype=float)
        rows, cols = self.jpos % self.n, self.jpos // self.n
        self._sens = (D, np.ascontiguousarray(steps, dtype=float), np.ascontiguousarray(scales, dtype=float),
                      np.ascontiguousarray(rows, dtype=np.int64), np.ascontiguousarray(cols, dtype=np.int64))
        self.n_sens = D.shape[0]
        if self.lib.drv_sens(self.handle, self.n_sens, D.shape[1], _ptr(D), _ptr(self._sens[1]), _ptr(self._sens[2]),
                             int(bool(error_control)), float(self.rtol), _ptr(self._sens[3]), _ptr(self._sens[4])):
            raise OSError("CVODES could not set up its forward sensitivities")

    def set_switches(self, angles, widths, max_width):
        """Switches of the right-hand side where y[0] (an angle) crosses `angles` (mod 2 pi): the
        sensitivities jump there by (f after - f before) s[0] / |y[1]|, f taken at the edges of
        the switch's band (half-width widths / |y[1]|, ignored beyond max_width), and their
        right-hand side is taken at the band's edge inside it. After set_sensitivities."""
        order = np.argsort(np.mod(angles, 2 * np.pi))
        self._switches = (np.ascontiguousarray(np.mod(angles, 2 * np.pi)[order], dtype=float),
                          np.ascontiguousarray(np.asarray(widths, float)[order]))
        if self.lib.drv_switches(self.handle, len(order), _ptr(self._switches[0]), _ptr(self._switches[1]),
                                 float(max_width)):
            raise OSError("CVODES could not set up its root finding")

    def set_roots(self, call, slots, offsets, output, n_out, state_idx, touch):
        """Switching functions located by CVODES: the kernel call's output `output` (its first
        n_out values; the state's pieces y[offsets[i]:] at its input slots[i]), then the states
        y[state_idx]; a value below `touch` in size counts as zero."""
        self._g = (call, np.asarray(slots, dtype=np.int64), np.asarray(offsets, dtype=np.int64),
                   np.zeros(max(n_out, 1)), np.asarray(state_idx, dtype=np.int64))
        call.res[:] = 0
        call.res[output] = _ptr(self._g[3])
        self.n_roots = n_out + len(state_idx)
        self._found = np.zeros(self.n_roots, dtype=np.int32)
        if self.lib.drv_roots(self.handle, call.address(), _ptr(call.arg), _ptr(call.res), _ptr(call.iw),
                              _ptr(call.w), len(slots), _ptr(self._g[1]), _ptr(self._g[2]), n_out, _ptr(self._g[3]),
                              len(state_idx), _ptr(self._g[4]), float(touch)):
            raise OSError("CVODES could not set up its root finding")

    def run(self, t0, y0, touts, s0=None):
        """y at each of touts (increasing, > t0) from y0 at t0 -> (m, n). The solver carries on
        without a restart when (t0, y0) is where the last call ended. With switching functions
        it stops at the first root: fewer rows, and self.root = (time, state, indices). With
        sensitivities: s0 (ns, n) their start, self.sensitivities (m, ns, n) at touts."""
        touts = np.ascontiguousarray(touts, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        resume = (self.last is not None and self.last[0] == t0 and np.array_equal(self.last[1], y0)
                  and s0 is None)
        Y = np.empty((touts.size, self.n))
        S0 = np.ascontiguousarray(np.zeros((self.n_sens, self.n)) if s0 is None else s0, dtype=float)
        SY = np.empty((touts.size, self.n_sens, self.n))
        done, t_root, y_root = ctypes.c_int(), ctypes.c_double(), np.empty(self.n)
        found = self._found if self.n_roots else np.zeros(1, dtype=np.int32)
        flag = self.lib.drv_run(self.handle, float(t0), _ptr(y0), int(resume), touts.size, _ptr(touts), _ptr(Y),
                                _ptr(self.stats_now), ctypes.byref(done), ctypes.byref(t_root), _ptr(y_root),
                                _ptr(found), _ptr(S0), _ptr(SY))
        if flag < 0:
            self.last = None
            msg = self.lib.drv_message(self.handle).decode(errors="replace")
            raise SolverError(f"CVODES failed (flag {flag}): {msg or 'no message'}")
        Y = Y[:done.value]
        self.sensitivities = SY[:done.value] if self.n_sens else None
        self.root = None
        if flag == 2:  # CV_ROOT_RETURN
            self.root = (t_root.value, y_root, np.nonzero(found)[0])
            self.last = (t_root.value, y_root.copy())
        else:
            self.last = (float(touts[-1]), Y[-1].copy())
        return Y

    @property
    def stats(self) -> dict:
        return dict(zip(STAT_NAMES, (int(v) for v in self.stats_now)))

    def __del__(self):
        if getattr(self, "handle", None) and self.lib is not None:
            self.lib.drv_free(self.handle)
            self.handle = None
