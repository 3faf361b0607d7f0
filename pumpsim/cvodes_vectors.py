"""C source of the direct CVODES driver's own serial vector operations (part of
cvodes_source.SOURCE): SUNDIALS' arithmetic, compiled with the driver."""

VECTOR_OPS = r"""/* The serial vector's operations that CVODES calls at every step, compiled with the driver: the
   same arithmetic, element by element and in the same order, as SUNDIALS' serial vector (its
   special cases of LinearSum included: x + y, c (x + y), ... round alike only where written alike),
   so the results do not change; a distribution's SUNDIALS may be built without optimisation
   (Debian's 6.4: -O0, where these loops were a third of CVODES' own work). */
#define VLEN(v) NV_LENGTH_S(v)
#define VD(v) NV_DATA_S(v)
static void fv_linearsum(sunrealtype a, N_Vector x, sunrealtype b, N_Vector y, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x), *yd = VD(y); double *zd = VD(z);
  if (a == b && !(a == 1.0 || a == -1.0)) { for (long i = 0; i < n; i++) zd[i] = a * (xd[i] + yd[i]); return; }
  if (a == -b && !(a == 1.0 || a == -1.0)) { for (long i = 0; i < n; i++) zd[i] = a * (xd[i] - yd[i]); return; }
  /* every other case of SUNDIALS' (axpy, sum, difference, a x + y, a x - y, general) is a x + b y
     rounded alike: products by +-1 are exact */
  for (long i = 0; i < n; i++) zd[i] = (a * xd[i]) + (b * yd[i]);
}
static void fv_const(sunrealtype c, N_Vector z) {
  long n = VLEN(z); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = c;
}
static void fv_prod(N_Vector x, N_Vector y, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x), *yd = VD(y); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = xd[i] * yd[i];
}
static void fv_div(N_Vector x, N_Vector y, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x), *yd = VD(y); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = xd[i] / yd[i];
}
static void fv_scale(sunrealtype c, N_Vector x, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = c * xd[i];
}
static void fv_abs(N_Vector x, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = fabs(xd[i]);
}
static void fv_inv(N_Vector x, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = 1.0 / xd[i];
}
static void fv_addconst(N_Vector x, sunrealtype b, N_Vector z) {
  long n = VLEN(x); const double *xd = VD(x); double *zd = VD(z);
  for (long i = 0; i < n; i++) zd[i] = xd[i] + b;
}
static sunrealtype fv_wsqrsum(N_Vector x, N_Vector w) {
  long n = VLEN(x); const double *xd = VD(x), *wd = VD(w); double sum = 0.0;
  for (long i = 0; i < n; i++) { double q = xd[i] * wd[i]; sum += q * q; }
  return sum;
}
static sunrealtype fv_wrmsnorm(N_Vector x, N_Vector w) { return sqrt(fv_wsqrsum(x, w) / VLEN(x)); }
static sunrealtype fv_maxnorm(N_Vector x) {
  long n = VLEN(x); const double *xd = VD(x); double m = 0.0;
  for (long i = 0; i < n; i++) if (fabs(xd[i]) > m) m = fabs(xd[i]);
  return m;
}
static sunrealtype fv_min(N_Vector x) {
  long n = VLEN(x); const double *xd = VD(x); double m = xd[0];
  for (long i = 1; i < n; i++) if (xd[i] < m) m = xd[i];
  return m;
}

/* v's (and its clones') hot operations by the driver's own */
static void fast_ops(N_Vector v) {
  N_Vector_Ops o = v->ops;
  o->nvlinearsum = fv_linearsum; o->nvconst = fv_const; o->nvprod = fv_prod; o->nvdiv = fv_div;
  o->nvscale = fv_scale; o->nvabs = fv_abs; o->nvinv = fv_inv; o->nvaddconst = fv_addconst;
  o->nvwrmsnorm = fv_wrmsnorm; o->nvwsqrsumlocal = fv_wsqrsum; o->nvmaxnorm = fv_maxnorm; o->nvmaxnormlocal = fv_maxnorm;
  o->nvmin = fv_min; o->nvminlocal = fv_min;
}

"""
