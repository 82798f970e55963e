/* Hand-written reference for the seed FWI problem: a plain C leapfrog and its exact adjoint, the
 * lower limit that flexipde's gradient is measured against (run/bench_peers.sh).
 *
 *   u_tt = c(x)^2 u_xx on [0, 1], u = 0 at both walls, n points, dt, T = steps * dt
 *   u_0 = exp(-((x - 0.5)/0.2)^2),  v_0 = -c u_0'  (a right-moving pulse), walls zero
 *   Stormer-Verlet in position form (the same scheme as flexipde's -ts_type leapfrog):
 *     u_1     = u_0 + dt v_0 + dt^2/2 a(u_0),      a(u)_i = c_i^2 (u_{i-1} - 2 u_i + u_{i+1}) / h^2
 *     u_{k+1} = 2 u_k - u_{k-1} + dt^2 a(u_k)
 *   J(c) = 0.5 || u_n - d ||^2 with d from c = 1 (the same code), gradient with respect to every c_i.
 *
 * Adjoint (lam_k = dJ/du_k through the recurrence; B_k = dt^2 diag(c^2) D2, D2 symmetric):
 *   lam_n = u_n - d; lam_{k-1} = (2I + B^T) lam_k - lam_{k+1}  (k = n-1 .. 1, lam_{n+1} = 0)
 *   dJ/dc_i = sum_{k=1}^{n-1} lam_{k+1,i} dt^2 2 c_i (D2 u_k)_i
 *             + lam_{1,i} (dt dv0_i/dc_i + dt^2 c_i (D2 u_0)_i),   dv0_i/dc_i = -u0'_i
 *   with lam_0 = (I + B^T/2) lam_1 - lam_2 (not needed for dJ/dc).
 *
 *   cc -O3 -o /tmp/reference_leapfrog run/reference_leapfrog.c -lm
 *   /tmp/reference_leapfrog [n=1000] [steps=5000] [dt=5e-4] [c0=0.9] [repeats=7] [gradient_out]
 * prints J, ||dJ/dc||, and the median wall time of value+gradient over the repeats (the forward
 * stores every u_k, like flexipde's full storage), then the median of a forward solve alone (three
 * rolling rows, nothing stored: what the gradient's cost is compared with); gradient_out receives
 * dJ/dc as text.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "reference_common.h"

/* out = D2 u (interior; zero at the walls), h2 = 1/h^2 */
static void d2(int n, const double *u, double *out, double h2) {
  out[0] = out[n - 1] = 0;
  for (int i = 1; i < n - 1; ++i) out[i] = (u[i - 1] - 2 * u[i] + u[i + 1]) * h2;
}

/* Forward: U holds u_0 .. u_steps (steps+1 rows of n). */
static void forward(int n, int steps, double dt, const double *c, const double *u0, const double *du0, double *U,
                    double *w) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  memcpy(U, u0, sizeof(double) * n);
  d2(n, u0, w, h2);
  double *u1 = U + n;
  for (int i = 0; i < n; ++i) {
    const int wall = i == 0 || i == n - 1;
    const double v0 = wall ? 0 : -c[i] * du0[i];
    u1[i] = wall ? 0 : u0[i] + dt * v0 + 0.5 * dt2 * c[i] * c[i] * w[i];
  }
  for (int k = 1; k < steps; ++k) {
    const double *um = U + (size_t)(k - 1) * n, *uk = U + (size_t)k * n;
    double *up = U + (size_t)(k + 1) * n;
    up[0] = up[n - 1] = 0;
    for (int i = 1; i < n - 1; ++i)
      up[i] = 2 * uk[i] - um[i] + dt2 * c[i] * c[i] * (uk[i - 1] - 2 * uk[i] + uk[i + 1]) * h2;
  }
}

/* The value alone: the same recurrence in three rolling rows, nothing stored. */
static double value(int n, int steps, double dt, const double *c, const double *u0, const double *du0,
                    const double *d, double *a, double *b, double *e, double *w) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  d2(n, u0, w, h2);
  for (int i = 0; i < n; ++i) {
    const int wall = i == 0 || i == n - 1;
    a[i] = u0[i];
    b[i] = wall ? 0 : u0[i] + dt * (-c[i] * du0[i]) + 0.5 * dt2 * c[i] * c[i] * w[i];
  }
  for (int k = 1; k < steps; ++k) { /* a = u_{k-1}, b = u_k -> e = u_{k+1} */
    e[0] = e[n - 1] = 0;
    for (int i = 1; i < n - 1; ++i) e[i] = 2 * b[i] - a[i] + dt2 * c[i] * c[i] * (b[i - 1] - 2 * b[i] + b[i + 1]) * h2;
    double *t = a;
    a = b;
    b = e;
    e = t;
  }
  double J = 0;
  for (int i = 0; i < n; ++i) J += 0.5 * (b[i] - d[i]) * (b[i] - d[i]);
  return J;
}

/* Value and gradient; returns J. */
static double gradient(int n, int steps, double dt, const double *c, const double *u0, const double *du0,
                       const double *d, double *U, double *g, double *la, double *lb, double *lc, double *w) {
  const double h = 1.0 / (n - 1), h2 = 1.0 / (h * h), dt2 = dt * dt;
  forward(n, steps, dt, c, u0, du0, U, w);
  const double *un = U + (size_t)steps * n;
  double J = 0;
  /* lam_{k+1} in lb, lam_{k+2} in lc, lam_k computed into la */
  for (int i = 0; i < n; ++i) {
    lb[i] = un[i] - d[i];
    J += 0.5 * lb[i] * lb[i];
    lc[i] = 0;
    g[i] = 0;
  }
  for (int k = steps - 1; k >= 1; --k) { /* lb = lam_{k+1}: accumulate the c-gradient of step k -> k+1, then lam_k */
    const double *uk = U + (size_t)k * n;
    for (int i = 1; i < n - 1; ++i) g[i] += lb[i] * dt2 * 2 * c[i] * (uk[i - 1] - 2 * uk[i] + uk[i + 1]) * h2;
    /* s = c^2 lam_{k+1} (walls zero), lam_k = 2 lam_{k+1} + dt^2 D2 s - lam_{k+2} */
    for (int i = 0; i < n; ++i) w[i] = (i == 0 || i == n - 1) ? 0 : c[i] * c[i] * lb[i];
    la[0] = la[n - 1] = 0;
    for (int i = 1; i < n - 1; ++i) la[i] = 2 * lb[i] + dt2 * (w[i - 1] - 2 * w[i] + w[i + 1]) * h2 - lc[i];
    double *t = lc;
    lc = lb;
    lb = la;
    la = t;
  }
  /* lb = lam_1: the start u_1 = u_0 + dt v_0(c) + dt^2/2 c^2 D2 u_0 */
  d2(n, u0, w, h2);
  for (int i = 1; i < n - 1; ++i) g[i] += lb[i] * (-dt * du0[i] + dt2 * c[i] * w[i]);
  return J;
}

int main(int argc, char **argv) {
  const int n = argc > 1 ? atoi(argv[1]) : 1000, steps = argc > 2 ? atoi(argv[2]) : 5000;
  const double dt = argc > 3 ? atof(argv[3]) : 5e-4, c0 = argc > 4 ? atof(argv[4]) : 0.9;
  const int repeats = argc > 5 ? atoi(argv[5]) : 7;
  const char *out = argc > 6 ? argv[6] : NULL;
  const double h = 1.0 / (n - 1);
  double *u0 = malloc(sizeof(double) * n), *du0 = malloc(sizeof(double) * n), *c = malloc(sizeof(double) * n),
         *ct = malloc(sizeof(double) * n), *d = malloc(sizeof(double) * n), *g = malloc(sizeof(double) * n),
         *la = malloc(sizeof(double) * n), *lb = malloc(sizeof(double) * n), *lc = malloc(sizeof(double) * n),
         *w = malloc(sizeof(double) * n), *U = malloc(sizeof(double) * (size_t)(steps + 1) * n),
         *times = malloc(sizeof(double) * (repeats > 0 ? repeats : 1));
  if (!u0 || !du0 || !c || !ct || !d || !g || !la || !lb || !lc || !w || !U || !times) {
    fprintf(stderr, "reference_leapfrog: out of memory\n");
    return 1;
  }
  for (int i = 0; i < n; ++i) {
    const double s = (i * h - 0.5) / 0.2, e = exp(-s * s);
    const int wall = i == 0 || i == n - 1;
    u0[i] = wall ? 0 : e;
    du0[i] = wall ? 0 : -2 * s / 0.2 * e;
    c[i] = c0;
    ct[i] = 1.0;
  }
  forward(n, steps, dt, ct, u0, du0, U, w); /* data from c = 1 */
  memcpy(d, U + (size_t)steps * n, sizeof(double) * n);
  double J = 0;
  for (int r = 0; r < repeats; ++r) {
    const double t0 = now();
    J = gradient(n, steps, dt, c, u0, du0, d, U, g, la, lb, lc, w);
    times[r] = now() - t0;
  }
  if (repeats <= 0) J = gradient(n, steps, dt, c, u0, du0, d, U, g, la, lb, lc, w);
  double gn = 0;
  for (int i = 0; i < n; ++i) gn += g[i] * g[i];
  qsort(times, repeats > 0 ? repeats : 1, sizeof(double), cmp);
  const int m = repeats > 0 ? repeats : 1;
  const double median = m % 2 ? times[m / 2] : 0.5 * (times[m / 2 - 1] + times[m / 2]);
  printf("reference: n %d, %d steps of %g, J = %.12e, ||dJ/dc|| = %.12e, value+gradient median %.6f s (min %.6f) over %d\n",
         n, steps, dt, J, sqrt(gn), median, times[0], repeats);
  double Jv = 0;
  for (int r = 0; r < m; ++r) {
    const double t0 = now();
    Jv = value(n, steps, dt, c, u0, du0, d, la, lb, lc, w);
    times[r] = now() - t0;
  }
  qsort(times, m, sizeof(double), cmp);
  const double fmed = m % 2 ? times[m / 2] : 0.5 * (times[m / 2 - 1] + times[m / 2]);
  printf("reference forward: J = %.12e, forward median %.6f s (min %.6f), value+gradient / forward %.2f\n", Jv, fmed,
         times[0], median / fmed);
  if (out) {
    FILE *f = fopen(out, "w");
    if (!f) {
      fprintf(stderr, "reference_leapfrog: cannot write %s\n", out);
      return 1;
    }
    for (int i = 0; i < n; ++i) fprintf(f, "%.17e\n", g[i]);
    fclose(f);
  }
  free(u0), free(du0), free(c), free(ct), free(d), free(g), free(la), free(lb), free(lc), free(w), free(U), free(times);
  return 0;
}
