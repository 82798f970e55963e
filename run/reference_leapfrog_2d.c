/* Hand-written 2D reference for throughput (run/bench_peers.sh, scale part): the leapfrog for
 * u_tt = c(x,y)^2 (u_xx + u_yy) on [0,1]^2 with u = 0 on the boundary, 5-point Laplacian, n x n
 * points, u_0 a Gaussian pulse of width 0.05 at the centre, v_0 = 0 (as flexipde's
 * -model wave2d -wave2d_ic pulse -wave2d_sponge_width 0), J = 0.5 ||u_n - d||^2 with d from c = 1,
 * and the exact adjoint for dJ/dc (one value per point). Same recurrences as reference_leapfrog.c:
 *   u_1 = u_0 + dt^2/2 c^2 L u_0,  u_{k+1} = 2 u_k - u_{k-1} + dt^2 c^2 L u_k
 *   lam_n = u_n - d,  lam_{k-1} = 2 lam_k + dt^2 L (c^2 lam_k) - lam_{k+1}
 *   dJ/dc = sum_k lam_{k+1} dt^2 2 c L u_k  (+ lam_1 dt^2 c L u_0 for the start)
 *
 *   cc -O3 -o /tmp/reference_leapfrog_2d run/reference_leapfrog_2d.c -lm
 *   /tmp/reference_leapfrog_2d [n=2000] [steps=100] [dt=2e-4] [c0=0.9] [repeats=3]
 * prints J, ||dJ/dc|| and the median wall time of value+gradient (the forward stores every u_k, like
 * flexipde's full storage), then the median of a value alone (three rolling levels, nothing stored:
 * what a gradient's cost is compared with) and their ratio.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "reference_common.h"

/* L u at interior point (i, j) of an n x n array, h2 = 1/h^2 */
#define LAP(u, i, j) (((u)[(j) * n + (i) - 1] + (u)[(j) * n + (i) + 1] + (u)[((j) - 1) * n + (i)] + (u)[((j) + 1) * n + (i)] - 4 * (u)[(j) * n + (i)]) * h2)

static void forward(int n, int steps, double dt, const double *c, double *U) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  const size_t N = (size_t)n * n;
  const double *u0 = U;
  double *u1 = U + N;
  memset(u1, 0, sizeof(double) * N);
  for (int j = 1; j < n - 1; ++j)
    for (int i = 1; i < n - 1; ++i) u1[j * n + i] = u0[j * n + i] + 0.5 * dt2 * c[j * n + i] * c[j * n + i] * LAP(u0, i, j);
  for (int k = 1; k < steps; ++k) {
    const double *um = U + (size_t)(k - 1) * N, *uk = U + (size_t)k * N;
    double *up = U + (size_t)(k + 1) * N;
    memset(up, 0, sizeof(double) * n);
    memset(up + (size_t)(n - 1) * n, 0, sizeof(double) * n);
    for (int j = 1; j < n - 1; ++j) {
      up[j * n] = up[j * n + n - 1] = 0;
      for (int i = 1; i < n - 1; ++i)
        up[j * n + i] = 2 * uk[j * n + i] - um[j * n + i] + dt2 * c[j * n + i] * c[j * n + i] * LAP(uk, i, j);
    }
  }
}

/* J alone: the same recurrence on three rolling levels (a, b, n_ of N each), nothing stored */
static double value(int n, int steps, double dt, const double *c, const double *u0, const double *d, double *a,
                    double *b, double *nx) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  const size_t N = (size_t)n * n;
  memcpy(a, u0, sizeof(double) * N);
  memset(b, 0, sizeof(double) * N);
  memset(nx, 0, sizeof(double) * N);
  for (int j = 1; j < n - 1; ++j)
    for (int i = 1; i < n - 1; ++i) b[j * n + i] = a[j * n + i] + 0.5 * dt2 * c[j * n + i] * c[j * n + i] * LAP(a, i, j);
  for (int k = 1; k < steps; ++k) {
    const double *um = a, *uk = b;
    double *up = nx;
    for (int j = 1; j < n - 1; ++j)
      for (int i = 1; i < n - 1; ++i)
        up[j * n + i] = 2 * uk[j * n + i] - um[j * n + i] + dt2 * c[j * n + i] * c[j * n + i] * LAP(uk, i, j);
    double *t = a;
    a = b;
    b = nx;
    nx = t;
  }
  const double *un = steps >= 1 ? b : a;
  double J = 0;
  for (size_t p = 0; p < N; ++p) J += 0.5 * (un[p] - d[p]) * (un[p] - d[p]);
  return J;
}

static double gradient(int n, int steps, double dt, const double *c, const double *d, double *U, double *g, double *la,
                       double *lb, double *lc, double *w) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  const size_t N = (size_t)n * n;
  forward(n, steps, dt, c, U);
  const double *un = U + (size_t)steps * N;
  double J = 0;
  for (size_t p = 0; p < N; ++p) {
    lb[p] = un[p] - d[p];
    J += 0.5 * lb[p] * lb[p];
    lc[p] = 0;
    g[p] = 0;
    la[p] = 0;
  }
  for (int k = steps - 1; k >= 1; --k) {
    const double *uk = U + (size_t)k * N;
    for (int j = 1; j < n - 1; ++j)
      for (int i = 1; i < n - 1; ++i) g[j * n + i] += lb[j * n + i] * dt2 * 2 * c[j * n + i] * LAP(uk, i, j);
    for (size_t p = 0; p < N; ++p) w[p] = c[p] * c[p] * lb[p];
    for (int i = 0; i < n; ++i) w[i] = w[(size_t)(n - 1) * n + i] = 0;
    for (int j = 0; j < n; ++j) w[j * n] = w[j * n + n - 1] = 0;
    for (int j = 1; j < n - 1; ++j)
      for (int i = 1; i < n - 1; ++i) la[j * n + i] = 2 * lb[j * n + i] + dt2 * LAP(w, i, j) - lc[j * n + i];
    double *t = lc;
    lc = lb;
    lb = la;
    la = t;
  }
  for (int j = 1; j < n - 1; ++j)
    for (int i = 1; i < n - 1; ++i) g[j * n + i] += lb[j * n + i] * dt2 * c[j * n + i] * LAP(U, i, j);
  return J;
}

int main(int argc, char **argv) {
  const int n = argc > 1 ? atoi(argv[1]) : 2000, steps = argc > 2 ? atoi(argv[2]) : 100;
  const double dt = argc > 3 ? atof(argv[3]) : 2e-4, c0 = argc > 4 ? atof(argv[4]) : 0.9;
  const int repeats = argc > 5 ? atoi(argv[5]) : 3;
  const size_t N = (size_t)n * n;
  const double h = 1.0 / (n - 1);
  double *c = malloc(sizeof(double) * N), *ct = malloc(sizeof(double) * N), *d = malloc(sizeof(double) * N),
         *g = malloc(sizeof(double) * N), *la = malloc(sizeof(double) * N), *lb = malloc(sizeof(double) * N),
         *lc = malloc(sizeof(double) * N), *w = malloc(sizeof(double) * N),
         *U = malloc(sizeof(double) * (size_t)(steps + 1) * N), *times = malloc(sizeof(double) * (repeats > 0 ? repeats : 1));
  if (!c || !ct || !d || !g || !la || !lb || !lc || !w || !U || !times) {
    fprintf(stderr, "reference_leapfrog_2d: out of memory\n");
    return 1;
  }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = i * h - 0.5, y = j * h - 0.5, s2 = (x * x + y * y) / (0.05 * 0.05);
      const int wall = i == 0 || j == 0 || i == n - 1 || j == n - 1;
      U[(size_t)j * n + i] = wall ? 0 : exp(-s2);
      c[(size_t)j * n + i] = c0;
      ct[(size_t)j * n + i] = 1.0;
    }
  forward(n, steps, dt, ct, U);
  memcpy(d, U + (size_t)steps * N, sizeof(double) * N);
  double J = 0;
  const int m = repeats > 0 ? repeats : 1;
  for (int r = 0; r < m; ++r) {
    const double t0 = now();
    J = gradient(n, steps, dt, c, d, U, g, la, lb, lc, w);
    times[r] = now() - t0;
  }
  double gn = 0;
  for (size_t p = 0; p < N; ++p) gn += g[p] * g[p];
  qsort(times, m, sizeof(double), cmp);
  const double median = m % 2 ? times[m / 2] : 0.5 * (times[m / 2 - 1] + times[m / 2]);
  printf("reference 2d: n %d x %d, %d steps of %g, J = %.12e, ||dJ/dc|| = %.12e, value+gradient median %.6f s (min %.6f) over %d\n",
         n, n, steps, dt, J, sqrt(gn), median, times[0], m);
  double Jv = 0;
  double *u0 = malloc(sizeof(double) * N);
  if (!u0) {
    fprintf(stderr, "reference_leapfrog_2d: out of memory\n");
    return 1;
  }
  memcpy(u0, U, sizeof(double) * N);
  for (int r = 0; r < m; ++r) {
    const double t0 = now();
    Jv = value(n, steps, dt, c, u0, d, la, lb, lc);
    times[r] = now() - t0;
  }
  qsort(times, m, sizeof(double), cmp);
  const double fmed = m % 2 ? times[m / 2] : 0.5 * (times[m / 2 - 1] + times[m / 2]);
  printf("reference 2d forward: J = %.12e, forward median %.6f s (min %.6f), value+gradient / forward %.2f\n", Jv, fmed,
         times[0], median / fmed);
  free(u0);
  free(c), free(ct), free(d), free(g), free(la), free(lb), free(lc), free(w), free(U), free(times);
  return 0;
}
