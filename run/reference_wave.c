/* Hand-written reference for throughput (run/bench_throughput.sh): the acoustic wave u_tt = c(x)^2 Lap u
 * on [0,1]^dim (dim 2 or 3) by the leapfrog, with its exact discrete adjoint for dJ/dc, c one value per
 * point. The scene is flexipde's -model wave2d -wave2d_ic pulse -wave2d_c_field 1 (walls, -fd_order):
 *
 *   n points per direction, h = 1/(n-1); the points on the boundary (walls) are held at 0 and have no
 *   equation; stencils reaching beyond a wall read the odd reflection of the inside, u(-k) = -u(k).
 *   L u = sum_d (w_0 u + sum_{m=1..R} w_m (u(x - m h e_d) + u(x + m h e_d))) / h^2, order 2R = 2, 4, 8:
 *     order 2: w = -2, 1;  order 4: -5/2, 4/3, -1/12;  order 8: -205/72, 8/5, -1/5, 8/315, -1/560.
 *   With the odd reflection L is symmetric on the interior points (the mirrored entries -w_{i+j} are).
 *   u_0 = exp(-|x - 0.5|^2 / 0.05^2) inside, v_0 = 0; d = u_n with c = 1; J = 0.5 sum_p (u_n - d)_p^2.
 *
 * Damped leapfrog (sponge sigma(x) = sigma_max r^2, r = max(0, W - depth)/W, depth = distance to the
 * nearest wall; W = 0: sigma = 0, the plain leapfrog). With s = sigma dt/2, D = 1 + s, E = 1 - s,
 * a_k = c^2 L u_k, q = dt^2:
 *   D u_1     = D u_0 + dt v_0 + q/2 a_0           (the first half kick is implicit in the damping)
 *   D u_{k+1} = 2 u_k - E u_{k-1} + q a_k          (k = 1 .. n-1)
 * Adjoint (mu_k the multiplier of the equation for u_k; J depends on u_n alone, L = L^T):
 *   D mu_n     = u_n - d
 *   D mu_k     = 2 mu_{k+1} + q L(c^2 mu_{k+1}) - E mu_{k+2}      (k = n-1 .. 1, mu_{n+1} = 0)
 *   dJ/dc      = sum_{k=1..n-1} mu_{k+1} q 2 c L u_k + mu_1 q c L u_0
 * computed in nu_k = c^2 mu_k (c > 0), whose recurrence has the forward's form, so that the stencil
 * reads one array and c only at the point itself, and with the factor q / c taken out of the sum:
 *   D nu_n     = c^2 (u_n - d)
 *   D nu_k     = 2 nu_{k+1} + q c^2 L nu_{k+1} - E nu_{k+2}
 *   dJ/dc      = q / c (2 sum_{k=1..n-1} nu_{k+1} L u_k + nu_1 L u_0)
 * An adjoint step is one pass: it reads u_k, nu_{k+1}, nu_{k+2} (overwritten by nu_k), c and the sum.
 *
 * Layout: a level is n^dim doubles, x fastest, walls included (0). Beyond a wall along y or z a row is
 * the mirrored row with its sign folded into the weight; along x the first and last R - 1 interior
 * points take the mirror point by point, the rest run the plain stencil.
 * Memory: the gradient's forward stores every level (like flexipde's full storage), (steps + 1) n^dim
 * 8 bytes: 2D n = 1001, 100 steps 0.81 GB; 3D n = 101, 100 steps 0.83 GB; 3D n = 201, 100 steps 6.5 GB.
 * The value alone runs on three rolling levels and stores nothing.
 *
 *   cc -O3 -o /tmp/reference_wave run/reference_wave.c -lm
 *   /tmp/reference_wave [dim=2] [n=201] [steps=100] [dt=0: 0.25 h] [c0=0.9] [order=2] [W=0] [sigma_max=60]
 *                       [repeats=3] [check]
 * prints J, ||dJ/dc||, the median wall time of value+gradient and of the value alone and their ratio,
 * and point-updates per second of both ((n-2)^dim interior points x steps / time). `check` also
 * compares dJ/dc with central differences of J in a few entries of c and along one direction.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime under -std=c99 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "reference_common.h"

/* The kernels below are inlined into each (dim, radius) case with constant trip counts, so that the
 * stencil loops unroll and the loop over a row vectorises. */
#if defined(__GNUC__)
#define KERNEL static inline __attribute__((always_inline))
#else
#define KERNEL static inline
#endif

#define MAXR 4
#define MAXQ (4 * MAXR) /* neighbour rows along y and z */

typedef struct {
  int dim, n, R, steps;
  size_t N;            /* n^dim */
  double dt, q;        /* q = dt^2 */
  double cw, wx[MAXR]; /* dim w_0 / h^2 and w_m / h^2 */
  const double *E, *iD; /* 1 - s and 1 / (1 + s) per point; NULL without a sponge */
} Scene;

/* The stencil's neighbour rows of row (j, k) along y (and z in 3D): offsets from the row and their
 * weights, the sign of a mirrored row folded in. Returns how many. */
static int neighbour_rows(const Scene *S, int j, int k, ptrdiff_t *off, double *nw) {
  const int n = S->n;
  int nq = 0;
  for (int d = 1; d < S->dim; ++d)
    for (int m = 1; m <= S->R; ++m)
      for (int side = -1; side <= 1; side += 2) {
        int g = (d == 1 ? j : k) + side * m;
        double sign = 1;
        if (g < 0) g = -g, sign = -1;
        else if (g > n - 1) g = 2 * (n - 1) - g, sign = -1;
        off[nq] = (ptrdiff_t)(d == 1 ? g - j : g - k) * (d == 1 ? n : (ptrdiff_t)n * n);
        nw[nq++] = sign * S->wx[m - 1];
      }
  return nq;
}

/* L u at point i of a row (u points at the row's start); near the x walls the mirror point by point. */
KERNEL double lap_at(const double *u, ptrdiff_t i, int n, int R, int nq, int edge, double cw, const double *wx,
                     const ptrdiff_t *off, const double *nw) {
  double s = cw * u[i];
  if (!edge)
    for (int m = 1; m <= R; ++m) s += wx[m - 1] * (u[i - m] + u[i + m]);
  else
    for (int m = 1; m <= R; ++m) {
      ptrdiff_t a = i - m, b = i + m;
      const double sa = a < 0 ? -1 : 1, sb = b > n - 1 ? -1 : 1;
      if (a < 0) a = -a;
      if (b > n - 1) b = 2 * (n - 1) - b;
      s += wx[m - 1] * (sa * u[a] + sb * u[b]);
    }
  for (int p = 0; p < nq; ++p) s += nw[p] * u[i + off[p]];
  return s;
}

/* The stencil's constants copied into locals: stores to the state cannot reach them, so the compiler
 * keeps them in registers across the row. */
#define LOCAL_STENCIL                                                                                     \
  double wx[MAXR], nw[MAXQ];                                                                              \
  ptrdiff_t off[MAXQ];                                                                                    \
  for (int m = 0; m < R; ++m) wx[m] = wx_[m];                                                             \
  for (int p = 0; p < nq; ++p) off[p] = off_[p], nw[p] = nw_[p]
#define LAP(u) lap_at(u, i, n, R, nq, edge, cw, wx, off, nw)

/* One forward step on a row of points lo..hi-1 (first: the start u_1; um unused). */
KERNEL void step_points(ptrdiff_t lo, ptrdiff_t hi, int n, int R, int nq, int edge, int first, double cw,
                        const double *wx_, const ptrdiff_t *off_, const double *nw_, double q,
                        const double *restrict um, const double *restrict uk, double *restrict up,
                        const double *restrict c, const double *restrict E, const double *restrict iD) {
  LOCAL_STENCIL;
  if (!E) {
    if (first)
      for (ptrdiff_t i = lo; i < hi; ++i) up[i] = uk[i] + 0.5 * q * c[i] * c[i] * LAP(uk);
    else
      for (ptrdiff_t i = lo; i < hi; ++i) up[i] = 2 * uk[i] - um[i] + q * c[i] * c[i] * LAP(uk);
  } else {
    if (first)
      for (ptrdiff_t i = lo; i < hi; ++i) up[i] = uk[i] + 0.5 * q * c[i] * c[i] * LAP(uk) * iD[i];
    else
      for (ptrdiff_t i = lo; i < hi; ++i) up[i] = (2 * uk[i] - E[i] * um[i] + q * c[i] * c[i] * LAP(uk)) * iD[i];
  }
}

/* One adjoint step on points lo..hi-1: g += nu_{k+1} L u_k, then nu_k over nu_{k+2} (in place). */
KERNEL void adjoint_points(ptrdiff_t lo, ptrdiff_t hi, int n, int R, int nq, int edge, double cw,
                           const double *wx_, const ptrdiff_t *off_, const double *nw_, double q,
                           const double *restrict uk, const double *restrict nu1, double *restrict nu2,
                           const double *restrict c, double *restrict g, const double *restrict E,
                           const double *restrict iD) {
  LOCAL_STENCIL;
  if (!E)
    for (ptrdiff_t i = lo; i < hi; ++i) {
      g[i] += nu1[i] * LAP(uk);
      nu2[i] = 2 * nu1[i] + q * c[i] * c[i] * LAP(nu1) - nu2[i];
    }
  else
    for (ptrdiff_t i = lo; i < hi; ++i) {
      g[i] += nu1[i] * LAP(uk);
      nu2[i] = (2 * nu1[i] + q * c[i] * c[i] * LAP(nu1) - E[i] * nu2[i]) * iD[i];
    }
}
#undef LAP
#undef LOCAL_STENCIL

/* A row's points: the x-edge points (mirrored: 1..R-1 and n-R..n-2) and the bulk (n >= 2R + 2), with
 * the radius and the neighbour count as constants of each call so that the compiler unrolls the stencil. */
#define ROW_SPLIT(CALL, R_, NQ_)                                                                            \
  do {                                                                                                    \
    CALL(1, R_, R_, NQ_, 1);                                                                              \
    CALL(R_, n - (R_), R_, NQ_, 0);                                                                       \
    CALL(n - (R_), n - 1, R_, NQ_, 1);                                                                    \
  } while (0)
#define ROW_DISPATCH(CALL)                                                                                \
  do {                                                                                                    \
    switch (S->dim * 10 + S->R) {                                                                         \
    case 21: ROW_SPLIT(CALL, 1, 2); break;                                                                \
    case 22: ROW_SPLIT(CALL, 2, 4); break;                                                                \
    case 24: ROW_SPLIT(CALL, 4, 8); break;                                                                \
    case 31: ROW_SPLIT(CALL, 1, 4); break;                                                                \
    case 32: ROW_SPLIT(CALL, 2, 8); break;                                                                \
    default: ROW_SPLIT(CALL, 4, 16); break;                                                               \
    }                                                                                                     \
  } while (0)

/* u_{k+1} from u_k and u_{k-1} (first: u_1 from u_0). Writes interior points only. */
static void step(const Scene *S, const double *c, const double *um, const double *uk, double *up, int first) {
  const int n = S->n, nz = S->dim == 3 ? n - 1 : 1;
  for (int k = S->dim == 3 ? 1 : 0; k < nz; ++k)
    for (int j = 1; j < n - 1; ++j) {
      ptrdiff_t off[MAXQ];
      double nw[MAXQ];
      neighbour_rows(S, j, k, off, nw);
      const size_t r = (size_t)n * (j + (size_t)n * k);
      const double *E = S->E ? S->E + r : NULL, *iD = S->iD ? S->iD + r : NULL;
#define STEP_CALL(LO, HI, R_, NQ_, EDGE)                                                                  \
  step_points(LO, HI, n, R_, NQ_, EDGE, first, S->cw, S->wx, off, nw, S->q, first ? NULL : um + r, uk + r, up + r, \
              c + r, E, iD)
      ROW_DISPATCH(STEP_CALL);
#undef STEP_CALL
    }
}

static void adjoint_step(const Scene *S, const double *c, const double *uk, const double *nu1, double *nu2, double *g) {
  const int n = S->n, nz = S->dim == 3 ? n - 1 : 1;
  for (int k = S->dim == 3 ? 1 : 0; k < nz; ++k)
    for (int j = 1; j < n - 1; ++j) {
      ptrdiff_t off[MAXQ];
      double nw[MAXQ];
      neighbour_rows(S, j, k, off, nw);
      const size_t r = (size_t)n * (j + (size_t)n * k);
      const double *E = S->E ? S->E + r : NULL, *iD = S->iD ? S->iD + r : NULL;
#define ADJ_CALL(LO, HI, R_, NQ_, EDGE)                                                                   \
  adjoint_points(LO, HI, n, R_, NQ_, EDGE, S->cw, S->wx, off, nw, S->q, uk + r, nu1 + r, nu2 + r, c + r, g + r, E, iD)
      ROW_DISPATCH(ADJ_CALL);
#undef ADJ_CALL
    }
}

/* The end of the gradient: g = q / c (2 g + nu_1 L u_0). */
static void finish_gradient(const Scene *S, const double *c, const double *u0, const double *nu1, double *g) {
  const int n = S->n, nz = S->dim == 3 ? n - 1 : 1;
  for (int k = S->dim == 3 ? 1 : 0; k < nz; ++k)
    for (int j = 1; j < n - 1; ++j) {
      ptrdiff_t off[MAXQ];
      double nw[MAXQ];
      const int nq = neighbour_rows(S, j, k, off, nw);
      const size_t r = (size_t)n * (j + (size_t)n * k);
      for (int i = 1; i < n - 1; ++i)
        g[r + i] = S->q / c[r + i] *
                   (2 * g[r + i] + nu1[r + i] * lap_at(u0 + r, i, n, S->R, nq, 1, S->cw, S->wx, off, nw));
    }
}

/* J alone on three rolling levels (a, b, e; walls zero), nothing stored. */
static double value(const Scene *S, const double *c, const double *u0, const double *d, double *a, double *b, double *e) {
  memcpy(a, u0, sizeof(double) * S->N);
  step(S, c, NULL, a, b, 1);
  for (int k = 1; k < S->steps; ++k) { /* a = u_{k-1}, b = u_k -> e = u_{k+1} */
    step(S, c, a, b, e, 0);
    double *t = a;
    a = b, b = e, e = t;
  }
  const double *un = S->steps >= 1 ? b : a;
  double J = 0;
  for (size_t p = 0; p < S->N; ++p) J += 0.5 * (un[p] - d[p]) * (un[p] - d[p]);
  return J;
}

/* Every level into U (level 0 = u_0 already there; walls zero from the start). */
static void forward(const Scene *S, const double *c, double *U) {
  for (int k = 0; k < S->steps; ++k)
    step(S, c, k ? U + (size_t)(k - 1) * S->N : NULL, U + (size_t)k * S->N, U + (size_t)(k + 1) * S->N, k == 0);
}

/* J and dJ/dc (g); na and nb hold nu (walls zero). */
static double gradient(const Scene *S, const double *c, const double *d, double *U, double *g, double *na, double *nb) {
  const size_t N = S->N;
  forward(S, c, U);
  const double *un = U + (size_t)S->steps * N;
  double J = 0;
  for (size_t p = 0; p < N; ++p) {
    const double r = un[p] - d[p];
    J += 0.5 * r * r;
    na[p] = c[p] * c[p] * (S->iD ? r * S->iD[p] : r); /* nu_n */
    nb[p] = 0;                                         /* nu_{n+1} */
    g[p] = 0;
  }
  for (int k = S->steps - 1; k >= 1; --k) { /* na = nu_{k+1}, nb = nu_{k+2} -> nu_k */
    adjoint_step(S, c, U + (size_t)k * N, na, nb, g);
    double *t = na;
    na = nb, nb = t;
  }
  finish_gradient(S, c, U, na, g);
  return J;
}

static double median(double *t, int m) {
  qsort(t, m, sizeof(double), cmp);
  return m % 2 ? t[m / 2] : 0.5 * (t[m / 2 - 1] + t[m / 2]);
}

int main(int argc, char **argv) {
  const int dim = argc > 1 ? atoi(argv[1]) : 2, n = argc > 2 ? atoi(argv[2]) : 201, steps = argc > 3 ? atoi(argv[3]) : 100;
  const double h = 1.0 / (n - 1);
  double dt = argc > 4 ? atof(argv[4]) : 0;
  const double c0 = argc > 5 ? atof(argv[5]) : 0.9;
  const int order = argc > 6 ? atoi(argv[6]) : 2;
  const double W = argc > 7 ? atof(argv[7]) : 0, sigma_max = argc > 8 ? atof(argv[8]) : 60;
  const int repeats = argc > 9 ? atoi(argv[9]) : 3, check = argc > 10 && !strcmp(argv[10], "check");
  const int R = order / 2, m = repeats > 0 ? repeats : 1;
  if (dt <= 0) dt = 0.25 * h;
  if ((dim != 2 && dim != 3) || (order != 2 && order != 4 && order != 8) || n < 2 * R + 2 || steps < 1 || W < 0 || c0 <= 0) {
    fprintf(stderr, "reference_wave: dim 2|3, order 2|4|8, n >= order + 2, steps >= 1, W >= 0, c0 > 0\n");
    return 1;
  }
  const double w2[] = {-2.0, 1.0}, w4[] = {-30.0 / 12, 16.0 / 12, -1.0 / 12},
               w8[] = {-205.0 / 72, 8.0 / 5, -1.0 / 5, 8.0 / 315, -1.0 / 560};
  const double *w = order == 2 ? w2 : order == 4 ? w4 : w8;
  Scene S = {dim, n, R, steps, 1, dt, dt * dt, dim * w[0] / (h * h), {0}, NULL, NULL};
  for (int k = 0; k < dim; ++k) S.N *= (size_t)n;
  for (int k = 1; k <= R; ++k) S.wx[k - 1] = w[k] / (h * h);
  const size_t N = S.N, bytes = sizeof(double) * (size_t)(steps + 1) * N;
  double *c = malloc(sizeof(double) * N), *ct = malloc(sizeof(double) * N), *d = malloc(sizeof(double) * N),
         *g = malloc(sizeof(double) * N), *ma = malloc(sizeof(double) * N), *mb = malloc(sizeof(double) * N),
         *la = malloc(sizeof(double) * N), *lb = malloc(sizeof(double) * N), *lc = malloc(sizeof(double) * N),
         *u0 = malloc(sizeof(double) * N), *U = malloc(bytes), *times = malloc(sizeof(double) * m);
  double *E = W > 0 ? malloc(sizeof(double) * N) : NULL, *iD = W > 0 ? malloc(sizeof(double) * N) : NULL;
  if (!c || !ct || !d || !g || !ma || !mb || !la || !lb || !lc || !u0 || !U || !times || (W > 0 && (!E || !iD))) {
    fprintf(stderr, "reference_wave: out of memory (full storage alone needs %.2f GB)\n", bytes / 1e9);
    return 1;
  }
  /* every array written once here, walls included: they stay 0 and the pages are touched before timing */
  memset(U, 0, bytes);
  for (size_t p = 0; p < N; ++p) {
    int idx[3] = {(int)(p % n), (int)(p / n % n), dim == 3 ? (int)(p / n / n) : 0}, wall = 0;
    double r2 = 0, depth = W;
    for (int k = 0; k < dim; ++k) {
      const double x = idx[k] * h;
      wall = wall || idx[k] == 0 || idx[k] == n - 1;
      r2 += (x - 0.5) * (x - 0.5) / (0.05 * 0.05);
      depth = fmin(depth, fmin(x, 1 - x));
    }
    u0[p] = U[p] = wall ? 0 : exp(-r2);
    c[p] = c0, ct[p] = 1, g[p] = ma[p] = mb[p] = la[p] = lb[p] = lc[p] = 0;
    if (W > 0) {
      const double r = fmax(0, W - depth) / W, s = sigma_max * r * r * dt / 2;
      E[p] = 1 - s, iD[p] = 1 / (1 + s);
    }
  }
  S.E = E, S.iD = iD;
  forward(&S, ct, U);
  memcpy(d, U + (size_t)steps * N, sizeof(double) * N);

  double J = 0, Jv = 0, gn = 0;
  for (int r = 0; r < m; ++r) {
    const double t0 = now();
    J = gradient(&S, c, d, U, g, ma, mb);
    times[r] = now() - t0;
  }
  for (size_t p = 0; p < N; ++p) gn += g[p] * g[p];
  const double gmin = (qsort(times, m, sizeof(double), cmp), times[0]), gmed = median(times, m);
  for (int r = 0; r < m; ++r) {
    const double t0 = now();
    Jv = value(&S, c, u0, d, la, lb, lc);
    times[r] = now() - t0;
  }
  const double fmin_ = (qsort(times, m, sizeof(double), cmp), times[0]), fmed = median(times, m);
  const double updates = pow(n - 2, dim) * steps;
  printf("reference wave %dd order %d: n %d^%d, %d steps of %g, sponge %g (sigma_max %g), J = %.12e, ||dJ/dc|| = %.12e, "
         "value+gradient median %.6f s (min %.6f) over %d\n",
         dim, order, n, dim, steps, dt, W, sigma_max, J, sqrt(gn), gmed, gmin, m);
  printf("reference wave %dd order %d forward: J = %.12e, forward median %.6f s (min %.6f), value+gradient / forward %.2f\n",
         dim, order, Jv, fmed, fmin_, gmed / fmed);
  printf("reference wave %dd order %d throughput: forward %.4e point-updates/s, gradient %.4e point-updates/s "
         "(%.0f interior points x %d steps; full storage %.3f GB)\n",
         dim, order, updates / fmed, updates / gmed, pow(n - 2, dim), steps, bytes / 1e9);

  if (check) {
    /* central differences of J: single entries of c (the centre, two off the centre, one next to a wall:
     * 0 until the wave gets there) and one smooth direction; eps relative to c0 */
    const double eps = 1e-5 * c0;
    const size_t nc = n / 2, a = n / 2 + n / 16, b = n / 2 - n / 32, plane = dim == 3 ? (size_t)n * n : 0;
    const size_t pick[4] = {nc + n * nc + plane * nc, a + n * nc + plane * nc, b + n * a + plane * b, 1 + n * nc + plane * nc};
    for (int k = 0; k < 4; ++k) {
      const size_t p = pick[k];
      c[p] = c0 + eps;
      const double Jp = value(&S, c, u0, d, la, lb, lc);
      c[p] = c0 - eps;
      const double Jm = value(&S, c, u0, d, la, lb, lc);
      c[p] = c0;
      const double fd = (Jp - Jm) / (2 * eps);
      printf("check: dJ/dc[%zu] adjoint %.12e, central difference %.12e, difference %.2e (relative %.2e)\n", p, g[p], fd,
             fabs(fd - g[p]), fabs(fd - g[p]) / fmax(fabs(g[p]), 1e-300));
    }
    double *dc = malloc(sizeof(double) * N), gd = 0;
    if (!dc) return 1;
    for (size_t p = 0; p < N; ++p) {
      const double x = p % n * h, y = p / n % n * h, z = dim == 3 ? p / n / n * h : 0.5;
      dc[p] = sin(3 * x + 1) * cos(5 * y - 2) * (1 + z);
      gd += g[p] * dc[p];
    }
    for (size_t p = 0; p < N; ++p) c[p] = c0 + eps * dc[p];
    const double Jp = value(&S, c, u0, d, la, lb, lc);
    for (size_t p = 0; p < N; ++p) c[p] = c0 - eps * dc[p];
    const double Jm = value(&S, c, u0, d, la, lb, lc);
    for (size_t p = 0; p < N; ++p) c[p] = c0;
    const double fd = (Jp - Jm) / (2 * eps);
    printf("check: directional derivative adjoint %.12e, central difference %.12e, relative difference %.2e\n", gd, fd,
           fabs(fd - gd) / fabs(gd));
    free(dc);
  }
  free(c), free(ct), free(d), free(g), free(ma), free(mb), free(la), free(lb), free(lc), free(u0), free(U), free(times);
  free(E), free(iD);
  return 0;
}
