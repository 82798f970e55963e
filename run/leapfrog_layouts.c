/* What the state's layout and the stored accelerations cost a leapfrog sweep: the 2D wave
 * u_tt = c^2 (u_xx + u_yy) on [0,1]^2, u = 0 on the boundary, 5-point Laplacian L, n x n points, a
 * Gaussian pulse at the centre, v_0 = 0, 100 steps. Five hand-written forward sweeps of the same
 * scheme (Stormer-Verlet, kick-drift-kick, with a = c^2 L q):
 *
 *   interleaved, a kept   U = (q, v) per point (a DMDA with 2 dof, flexipde's state) and a[] kept
 *                         between steps; per row: kick and drift rows ahead, a on the row, the second
 *                         kick a row behind (flexipde's one-sweep step)
 *   interleaved, v_{k+1/2} the same U, the velocity kept at half steps: v += dt a(q) on row r, then
 *                         q += dt v on row r - 1 (no a[])
 *   separate,    a kept   q[] and v[] apart, otherwise as the first
 *   separate,    v_{k+1/2} q[] and v[] apart, otherwise as the second
 *   three levels          u_{k+1} = 2 u_k - u_{k-1} + dt^2 c^2 L u_k (Devito's form of the scheme)
 *
 * The half-step forms start from v_{-1/2} = v_0 - dt/2 a(q_0) (and u_{-1} = u_0 - dt v_{-1/2}), so all
 * five give the same u_n up to rounding: the printed sums agree. Nothing is stored for an adjoint.
 *
 *   cc -O3 -march=native -ffp-contract=off -o /tmp/leapfrog_layouts run/leapfrog_layouts.c -lm
 *   /tmp/leapfrog_layouts [n=2000] [steps=100] [repeats=3]
 * prints the median wall time of each sweep and its point-updates per second.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "reference_common.h"

/* a = c^2 L q on the interior of row r (q: row-major, `stride` entries per point) */
#define ACC(q, stride, r, i)                                                                              \
  (c2[(size_t)(r) * n + (i)] * h2 *                                                                       \
   ((q)[((size_t)(r) * n + (i) - 1) * (stride)] + (q)[((size_t)(r) * n + (i) + 1) * (stride)] +            \
    (q)[((size_t)((r) - 1) * n + (i)) * (stride)] + (q)[((size_t)((r) + 1) * n + (i)) * (stride)] -        \
    4 * (q)[((size_t)(r) * n + (i)) * (stride)]))

/* One step, kick-drift-kick with a[] kept: the kick and drift 3 rows ahead, a on row r, the second kick a
 * row behind. q and v: `st` entries per point apart (2: interleaved, 1: separate arrays). */
static inline __attribute__((always_inline)) void step_kept(double *q, double *v, double *a, const double *c2, int n,
                                                            double h2, double dt, const int st) {
  int drifted = 0, kicked = 0;
  for (int r = 0; r < n; ++r) {
    for (; drifted < n && drifted <= r + 3; ++drifted)
      for (size_t p = (size_t)drifted * n; p < (size_t)(drifted + 1) * n; ++p) {
        v[p * st] += 0.5 * dt * a[p];
        q[p * st] += dt * v[p * st];
      }
    if (r > 0 && r < n - 1)
      for (int i = 1; i < n - 1; ++i) a[(size_t)r * n + i] = ACC(q, st, r, i);
    for (; kicked < r; ++kicked)
      for (size_t p = (size_t)kicked * n; p < (size_t)(kicked + 1) * n; ++p) v[p * st] += 0.5 * dt * a[p];
  }
  for (; kicked < n; ++kicked)
    for (size_t p = (size_t)kicked * n; p < (size_t)(kicked + 1) * n; ++p) v[p * st] += 0.5 * dt * a[p];
}

/* One step with v at half steps: v += dt a(q) on row r, then q += dt v on row r - 1 (no a[]). */
static inline __attribute__((always_inline)) void step_half(double *q, double *v, const double *c2, int n, double h2,
                                                            double dt, const int st) {
  for (int r = 0; r < n; ++r) {
    if (r > 0 && r < n - 1)
      for (int i = 1; i < n - 1; ++i) v[((size_t)r * n + i) * st] += dt * ACC(q, st, r, i);
    if (r > 0)
      for (size_t p = (size_t)(r - 1) * n; p < (size_t)r * n; ++p) q[p * st] += dt * v[p * st];
  }
  for (size_t p = (size_t)(n - 1) * n; p < (size_t)n * n; ++p) q[p * st] += dt * v[p * st];
}

int main(int argc, char **argv) {
  const int n = argc > 1 ? atoi(argv[1]) : 2000, steps = argc > 2 ? atoi(argv[2]) : 100;
  const int repeats = argc > 3 ? atoi(argv[3]) : 3;
  if (n < 3 || steps < 1 || repeats < 1) {
    fprintf(stderr, "usage: leapfrog_layouts [n >= 3] [steps >= 1] [repeats >= 1]\n");
    return 1;
  }
  const double h = 1.0 / (n - 1), h2 = 1 / (h * h), dt = 0.5 * h / 0.9;
  const size_t N = (size_t)n * n;
  double *u = calloc(2 * N, 8), *q = calloc(N, 8), *v = calloc(N, 8), *a = calloc(N, 8), *w = calloc(N, 8);
  double *c2 = malloc(N * 8), *q0 = malloc(N * 8), *a0 = calloc(N, 8), *t = malloc(repeats * sizeof(double));
  if (!u || !q || !v || !a || !w || !c2 || !q0 || !a0 || !t) {
    fprintf(stderr, "leapfrog_layouts: out of memory\n");
    return 1;
  }
  for (size_t p = 0; p < N; ++p) c2[p] = 0.81;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) q0[(size_t)j * n + i] = exp(-400 * ((i * h - .5) * (i * h - .5) + (j * h - .5) * (j * h - .5)));
  for (int j = 0; j < n; ++j) /* the pulse is 0 to round-off on the boundary: held there */
    for (int i = 0; i < n; ++i)
      if (i == 0 || j == 0 || i == n - 1 || j == n - 1) q0[(size_t)j * n + i] = 0;
  for (int r = 1; r < n - 1; ++r)
    for (int i = 1; i < n - 1; ++i) a0[(size_t)r * n + i] = ACC(q0, 1, r, i);
  const char *names[5] = {"interleaved, a kept", "interleaved, v_{k+1/2}", "separate, a kept", "separate, v_{k+1/2}",
                          "three levels"};
  for (int variant = 0; variant < 5; ++variant) {
    double sum = 0;
    for (int rep = 0; rep < repeats; ++rep) {
      const int half = variant == 1 || variant == 3;
      for (size_t p = 0; p < N; ++p) { /* q_0; v_0 = 0 or v_{-1/2}; a(q_0) */
        const double v0 = half ? -0.5 * dt * a0[p] : 0;
        u[2 * p] = q[p] = q0[p], u[2 * p + 1] = v[p] = v0, a[p] = a0[p];
        w[p] = q0[p] + 0.5 * dt * dt * a0[p]; /* u_{-1} */
      }
      double *prev = w, *cur = q, *next = v;
      const double t0 = now();
      for (int s = 0; s < steps; ++s) {
        if (variant == 0) step_kept(u, u + 1, a, c2, n, h2, dt, 2);
        else if (variant == 2) step_kept(q, v, a, c2, n, h2, dt, 1);
        else if (variant == 1) step_half(u, u + 1, c2, n, h2, dt, 2);
        else if (variant == 3) step_half(q, v, c2, n, h2, dt, 1);
        else { /* three levels, rotating */
          for (int r = 1; r < n - 1; ++r)
            for (int i = 1; i < n - 1; ++i) {
              const size_t p = (size_t)r * n + i;
              next[p] = 2 * cur[p] - prev[p] + dt * dt * ACC(cur, 1, r, i);
            }
          double *old = prev;
          prev = cur, cur = next, next = old;
        }
      }
      t[rep] = now() - t0;
      const double *qn = variant == 4 ? cur : variant == 0 || variant == 1 ? u : q;
      const int st = variant == 0 || variant == 1 ? 2 : 1;
      sum = 0;
      for (size_t p = 0; p < N; ++p) sum += qn[p * st];
    }
    qsort(t, repeats, sizeof(double), cmp);
    printf("%-24s n %d, %d steps: %.4f s, %5.0f Mpt/s, sum of u_n %.12e\n", names[variant], n, steps, t[repeats / 2],
           (double)N * steps / t[repeats / 2] / 1e6, sum);
  }
  free(u), free(q), free(v), free(a), free(w), free(c2), free(q0), free(a0), free(t);
  return 0;
}
