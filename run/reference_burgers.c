/* Hand-written reference for the viscous Burgers gradient: a plain C classical RK4 and its exact
 * discrete adjoint, the lower limit that flexipde's gradient is measured against (run/bench_burgers.sh).
 *
 *   u_t + (u^2/2)_x = (nu(x) u_x)_x on [0, 1), periodic, N points, h = 1/N, x_i = i h
 *   G_i = Phi_{i+1/2} - Phi_{i-1/2},   Phi_{i+1/2} = -F(u_i, u_{i+1}) / h + nu_{i+1/2} (u_{i+1} - u_i) / h^2
 *   F(a, b) = max(a, 0)^2 / 2 + min(b, 0)^2 / 2 (Engquist-Osher),  nu_{i+1/2} = (nu_i + nu_{i+1}) / 2
 *   u_0 = sin(2 pi x);  classical RK4, steps = round(T / dt) equal steps of T / steps:
 *     Y1 = u_n, Y2 = u_n + dt/2 K1, Y3 = u_n + dt/2 K2, Y4 = u_n + dt K3,  K_s = G(Y_s)
 *     u_{n+1} = u_n + dt (K1 + 2 K2 + 2 K3 + K4) / 6
 *   J(nu) = 0.5 sum_i (u_i(T) - d_i)^2 (no h weight, as flexipde's terminal misfit), d = u(T) with nu_true.
 *
 * Adjoint (lam = dJ/du_{n+1}, from lam = u(T) - d; the stages Y_s of every step are stored in the forward):
 *   k4 = dt/6 lam,            y4 = A4^T k4
 *   k3 = dt/3 lam + dt   y4,  y3 = A3^T k3
 *   k2 = dt/3 lam + dt/2 y3,  y2 = A2^T k2
 *   k1 = dt/6 lam + dt/2 y2,  y1 = A1^T k1
 *   lam <- lam + y1 + y2 + y3 + y4,   dJ/dnu += B1^T k1 + B2^T k2 + B3^T k3 + B4^T k4
 * with A_s = dG/du and B_s = dG/dnu at Y_s. With e_{i+1/2} = w_i - w_{i+1} on each face:
 *   (A^T w)_i  = -(max(u_i, 0) e_{i+1/2} + min(u_i, 0) e_{i-1/2}) / h + (nu_{i-1/2} e_{i-1/2} - nu_{i+1/2} e_{i+1/2}) / h^2
 *   (B^T w)_i  = (e_{i+1/2} (u_{i+1} - u_i) + e_{i-1/2} (u_i - u_{i-1})) / (2 h^2)
 * Each stage (forward and adjoint) is one pass over the grid, in blocks of points that stay in L1: a
 * block's face quantities (Phi; or e, nu e / h^2, e (u_{i+1} - u_i) / (2 h^2)) once per face, then its
 * points. A scalar nu has the gradient sum_i dJ/dnu_i (dJ/dnu is accumulated per point either way).
 *
 *   cc -O3 -march=x86-64 -o /tmp/reference_burgers run/reference_burgers.c -lm
 *   /tmp/reference_burgers [N=128] [dt=1e-3] [T=0.5] [nu=0.01] [nu_true=0.02] [field=0] [repeats=7]
 * prints (one "key: values" line each) the scene, J and ||dJ/dnu||, the central-difference check
 * (a constant direction, and for a field also a random one), and the medians (min, max) of the wall
 * time of a forward solve alone (rolling rows, nothing stored) and of value+gradient (forward storing
 * the stages, then the adjoint) over the repeats, after one untimed gradient, and the medians of the
 * gradient's two parts.
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime under -std=c99 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "reference_common.h"

static double median(double *v, int n) {
  qsort(v, n, sizeof(double), cmp);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static const double PI = 3.14159265358979323846;

/* max(a, 0) and min(a, 0), exactly, without a branch (the loops vectorise) */
static inline double pos(double a) { return 0.5 * (a + fabs(a)); }
static inline double neg(double a) { return 0.5 * (a - fabs(a)); }

/* Phi on the face between a (left) and b (right) with face viscosity nf. */
static inline double phi(double a, double b, double nf, double ih, double ih2) {
  const double pa = pos(a), nb = neg(b);
  return -0.5 * (pa * pa + nb * nb) * ih + nf * (b - a) * ih2;
}

/* The grid is swept in blocks of BLOCK points: a block's faces go to a small array (in L1) in one
 * loop and its points are updated from it in the next, so that both loops vectorise and every face
 * is computed once (the block's last face is the next block's first). */
#define BLOCK 256

/* One forward stage: K = G(y); ynext = u + cy K (if ynext); acc = (first ? u : acc) + ca K. */
static void stage(int n, const double *restrict y, const double *restrict u, const double *restrict nu, double nus,
                  double ih, double ih2, double cy, double *restrict ynext, double ca, double *restrict acc, int first) {
  double f[BLOCK + 1];
  const double fwrap = phi(y[n - 1], y[0], nu ? 0.5 * (nu[n - 1] + nu[0]) : nus, ih, ih2); /* face n - 1/2 = -1/2 */
  f[0] = fwrap;
  for (int i0 = 0; i0 < n; i0 += BLOCK) {
    const int m = n - i0 < BLOCK ? n - i0 : BLOCK, mf = i0 + m == n ? m - 1 : m;
    const double *yb = y + i0;
    if (nu) {
      const double *nb = nu + i0;
      for (int j = 0; j < mf; ++j) f[j + 1] = phi(yb[j], yb[j + 1], 0.5 * (nb[j] + nb[j + 1]), ih, ih2);
    } else {
      for (int j = 0; j < mf; ++j) f[j + 1] = phi(yb[j], yb[j + 1], nus, ih, ih2);
    }
    if (mf < m) f[m] = fwrap;
    const double *ub = u + i0;
    double *ab = acc + i0;
    if (ynext) {
      double *yn = ynext + i0;
      if (first)
        for (int j = 0; j < m; ++j) {
          const double k = f[j + 1] - f[j];
          yn[j] = ub[j] + cy * k, ab[j] = ub[j] + ca * k;
        }
      else
        for (int j = 0; j < m; ++j) {
          const double k = f[j + 1] - f[j];
          yn[j] = ub[j] + cy * k, ab[j] += ca * k;
        }
    } else {
      for (int j = 0; j < m; ++j) ab[j] += ca * (f[j + 1] - f[j]);
    }
    f[0] = f[m];
  }
}

/* One RK4 step from u to unew; Y (if not NULL) receives Y2, Y3, Y4 (3 rows of n), else the rolling rows
 * ya, yb serve. */
static void rk4_step(int n, double dt, const double *u, double *unew, const double *nu, double nus, double *Y, double *ya,
                     double *yb) {
  const double h = 1.0 / n, ih = 1.0 / h, ih2 = ih * ih;
  double *y2 = Y ? Y : ya, *y3 = Y ? Y + n : yb, *y4 = Y ? Y + 2 * n : ya;
  stage(n, u, u, nu, nus, ih, ih2, 0.5 * dt, y2, dt / 6, unew, 1);
  stage(n, y2, u, nu, nus, ih, ih2, 0.5 * dt, y3, dt / 3, unew, 0);
  stage(n, y3, u, nu, nus, ih, ih2, dt, y4, dt / 3, unew, 0);
  stage(n, y4, u, nu, nus, ih, ih2, 0, NULL, dt / 6, unew, 0);
}

static void initial(int n, double *u) {
  for (int i = 0; i < n; ++i) u[i] = sin(2 * PI * (i * (1.0 / n)));
}

/* Forward alone: u(T) into ut (rolling rows a, b, c, e). */
static void forward(int n, int steps, double dt, const double *nu, double nus, double *ut, double *a, double *c,
                    double *e) {
  double *u = ut, *un = a;
  initial(n, u);
  for (int k = 0; k < steps; ++k) {
    rk4_step(n, dt, u, un, nu, nus, NULL, c, e);
    double *t = u;
    u = un, un = t;
  }
  if (u != ut) memcpy(ut, u, sizeof(double) * n);
}

static double misfit(int n, const double *u, const double *d) {
  double s = 0;
  for (int i = 0; i < n; ++i) s += (u[i] - d[i]) * (u[i] - d[i]);
  return 0.5 * s;
}

/* One adjoint stage: k = cl lam + cy ynext (ynext NULL: cl lam alone); yout = A^T k at the stored
 * stage y; lacc = (first ? lam : lacc) + yout; mu += B^T k. Per block: k at its points and the next
 * one, then its faces once each (e = k_i - k_{i+1}, s = nu_{i+1/2} e / h^2, b = e (y_{i+1} - y_i) / (2 h^2)),
 * then its points: (A^T k)_i = -(max(y_i, 0) e_r + min(y_i, 0) e_l) / h + s_l - s_r, (B^T k)_i = b_l + b_r. */
static void adjoint_stage(int n, const double *restrict y, const double *restrict lam, double cl,
                          const double *restrict ynext, double cy, const double *restrict nu, double nus, double ih,
                          double ih2, double *restrict yout, double *restrict lacc, int first, double *restrict mu) {
  double k[BLOCK + 1], E[BLOCK + 1], S[BLOCK + 1], M[BLOCK + 1];
  const double kn = ynext ? cl * lam[n - 1] + cy * ynext[n - 1] : cl * lam[n - 1];
  const double k0 = ynext ? cl * lam[0] + cy * ynext[0] : cl * lam[0];
  const double ew = kn - k0, nw = nu ? 0.5 * (nu[n - 1] + nu[0]) : nus; /* face n - 1/2 = -1/2 */
  const double sw = nw * ew * ih2, mw = 0.5 * ew * (y[0] - y[n - 1]) * ih2;
  E[0] = ew, S[0] = sw, M[0] = mw;
  for (int i0 = 0; i0 < n; i0 += BLOCK) {
    const int m = n - i0 < BLOCK ? n - i0 : BLOCK, mf = i0 + m == n ? m - 1 : m;
    const double *yb = y + i0, *lb = lam + i0;
    if (ynext) {
      const double *xb = ynext + i0;
      for (int j = 0; j <= mf; ++j) k[j] = cl * lb[j] + cy * xb[j]; /* mf + 1 <= m: inside the grid */
    } else {
      for (int j = 0; j <= mf; ++j) k[j] = cl * lb[j];
    }
    if (nu) {
      const double *nb = nu + i0;
      for (int j = 0; j < mf; ++j) {
        const double e = k[j] - k[j + 1];
        E[j + 1] = e, S[j + 1] = 0.5 * (nb[j] + nb[j + 1]) * e * ih2, M[j + 1] = 0.5 * e * (yb[j + 1] - yb[j]) * ih2;
      }
    } else {
      for (int j = 0; j < mf; ++j) {
        const double e = k[j] - k[j + 1];
        E[j + 1] = e, S[j + 1] = nus * e * ih2, M[j + 1] = 0.5 * e * (yb[j + 1] - yb[j]) * ih2;
      }
    }
    if (mf < m) E[m] = ew, S[m] = sw, M[m] = mw;
    double *ob = yout + i0, *ab = lacc + i0, *mb = mu + i0;
    if (first)
      for (int j = 0; j < m; ++j) {
        const double yi = yb[j];
        const double a = -(pos(yi) * E[j + 1] + neg(yi) * E[j]) * ih + S[j] - S[j + 1];
        ob[j] = a, ab[j] = lb[j] + a, mb[j] += M[j] + M[j + 1];
      }
    else
      for (int j = 0; j < m; ++j) {
        const double yi = yb[j];
        const double a = -(pos(yi) * E[j + 1] + neg(yi) * E[j]) * ih + S[j] - S[j + 1];
        ob[j] = a, ab[j] += a, mb[j] += M[j] + M[j + 1];
      }
    E[0] = E[m], S[0] = S[m], M[0] = M[m];
  }
}

/* Value and gradient: the forward stores u_n, Y2, Y3, Y4 of every step in S (4 n per step); mu
 * receives dJ/dnu_i (a scalar nu: their sum is dJ/dnu). Work rows: lam, lnew, ya, yb (n each);
 * times[0], times[1]: the forward storing the stages and the adjoint (wall seconds). */
static double gradient(int n, int steps, double dt, const double *nu, double nus, const double *d, double *S,
                       double *ut, double *mu, double *lam, double *lnew, double *ya, double *yb, double *times) {
  const double h = 1.0 / n, ih = 1.0 / h, ih2 = ih * ih;
  const size_t row = (size_t)4 * n;
  const double t0 = now();
  initial(n, S);
  for (int k = 0; k < steps; ++k) {
    double *u = S + k * row, *un = k + 1 < steps ? S + (k + 1) * row : ut;
    rk4_step(n, dt, u, un, nu, nus, u + n, NULL, NULL);
  }
  const double J = misfit(n, ut, d);
  const double t1 = now();
  for (int i = 0; i < n; ++i) lam[i] = ut[i] - d[i], mu[i] = 0;
  for (int k = steps - 1; k >= 0; --k) {
    const double *Y1 = S + k * row, *Y2 = Y1 + n, *Y3 = Y2 + n, *Y4 = Y3 + n;
    adjoint_stage(n, Y4, lam, dt / 6, NULL, 0, nu, nus, ih, ih2, ya, lnew, 1, mu);
    adjoint_stage(n, Y3, lam, dt / 3, ya, dt, nu, nus, ih, ih2, yb, lnew, 0, mu);
    adjoint_stage(n, Y2, lam, dt / 3, yb, 0.5 * dt, nu, nus, ih, ih2, ya, lnew, 0, mu);
    adjoint_stage(n, Y1, lam, dt / 6, ya, 0.5 * dt, nu, nus, ih, ih2, yb, lnew, 0, mu);
    double *t = lam;
    lam = lnew, lnew = t;
  }
  if (!nu) {
    double s = 0;
    for (int i = 0; i < n; ++i) s += mu[i];
    mu[0] = s;
  }
  if (times) times[0] = t1 - t0, times[1] = now() - t1;
  return J;
}

static double value(int n, int steps, double dt, const double *nu, double nus, const double *d, double *ut, double *a,
                    double *c, double *e) {
  forward(n, steps, dt, nu, nus, ut, a, c, e);
  return misfit(n, ut, d);
}

int main(int argc, char **argv) {
  const int n = argc > 1 ? atoi(argv[1]) : 128;
  const double dt0 = argc > 2 ? atof(argv[2]) : 1e-3, T = argc > 3 ? atof(argv[3]) : 0.5;
  const double nu0 = argc > 4 ? atof(argv[4]) : 0.01, nu_true = argc > 5 ? atof(argv[5]) : 0.02;
  const int field = argc > 6 ? atoi(argv[6]) : 0, repeats = argc > 7 ? atoi(argv[7]) : 7;
  if (n < 3 || !(dt0 > 0) || !(T > 0) || repeats < 0) {
    fprintf(stderr, "usage: %s [N >= 3] [dt > 0] [T > 0] [nu] [nu_true] [field 0/1] [repeats >= 0]\n", argv[0]);
    return 1;
  }
  const long ls = lround(T / dt0); /* as flexipde: a whole number of equal steps */
  const int steps = ls < 1 ? 1 : (int)ls;
  const double dt = T / steps;
  const int np = field ? n : 1;
  const int R = repeats > 0 ? repeats : 1;
  double *nu = malloc(sizeof(double) * n), *d = malloc(sizeof(double) * n), *ut = malloc(sizeof(double) * n);
  double *g = malloc(sizeof(double) * n), *w = malloc(sizeof(double) * 4 * n), *q = malloc(sizeof(double) * n);
  double *S = malloc(sizeof(double) * 4 * (size_t)n * steps);
  double *tf = malloc(sizeof(double) * R), *tg = malloc(sizeof(double) * R), *ts = malloc(sizeof(double) * R),
         *ta = malloc(sizeof(double) * R);
  if (!nu || !d || !ut || !g || !w || !q || !S || !tf || !tg || !ts || !ta) {
    fprintf(stderr, "reference_burgers: out of memory (%d points, %d steps)\n", n, steps);
    return 1;
  }
  double *w0 = w, *w1 = w + n, *w2 = w + 2 * n, *w3 = w + 3 * n;
  /* data from nu_true (constant: as a field or as a scalar, the same u(T)) */
  for (int i = 0; i < n; ++i) nu[i] = nu_true;
  forward(n, steps, dt, field ? nu : NULL, nu_true, d, w0, w1, w2);
  for (int i = 0; i < n; ++i) nu[i] = nu0;
  const double *nuf = field ? nu : NULL;

  const double J = gradient(n, steps, dt, nuf, nu0, d, S, ut, g, w0, w1, w2, w3, NULL);
  double gn = 0;
  for (int i = 0; i < np; ++i) gn += g[i] * g[i];
  gn = sqrt(gn);
  printf("scene: N %d, steps %d, dt %.6e, T %g, nu %g, nu_true %g, field %d, parameters %d\n", n, steps, dt, T, nu0,
         nu_true, field, np);
  printf("gradient: J = %.12e, ||dJ/dnu|| = %.12e\n", J, gn);
  if (!isfinite(J) || !isfinite(gn)) {
    fprintf(stderr, "reference_burgers: J or its gradient is not finite (RK4 unstable? 4 nu dt / h^2 = %g, dt / h = %g)\n",
            4 * fmax(nu0, nu_true) * dt * n * n, dt * n);
    return 2;
  }

  /* central differences, step 1e-4 nu: a constant direction (1 in every entry), and for a field a random one */
  for (int dir = 0; dir < (field ? 2 : 1); ++dir) {
    const double eps = 1e-4 * fabs(nu0);
    double gv = 0, Jp, Jm;
    srand(12345);
    for (int i = 0; i < np; ++i) {
      q[i] = dir == 0 ? 1.0 : 2.0 * rand() / RAND_MAX - 1.0;
      gv += g[i] * q[i];
    }
    if (field) {
      for (int i = 0; i < n; ++i) nu[i] = nu0 + eps * q[i];
      Jp = value(n, steps, dt, nu, 0, d, ut, w0, w1, w2);
      for (int i = 0; i < n; ++i) nu[i] = nu0 - eps * q[i];
      Jm = value(n, steps, dt, nu, 0, d, ut, w0, w1, w2);
      for (int i = 0; i < n; ++i) nu[i] = nu0;
    } else {
      Jp = value(n, steps, dt, NULL, nu0 + eps, d, ut, w0, w1, w2);
      Jm = value(n, steps, dt, NULL, nu0 - eps, d, ut, w0, w1, w2);
    }
    const double fd = (Jp - Jm) / (2 * eps);
    printf("check: direction %s, adjoint %.12e, central difference %.12e (eps %.1e), relative difference %.3e\n",
           dir == 0 ? "constant" : "random", gv, fd, eps, fabs(gv - fd) / fmax(fabs(fd), 1e-300));
  }

  for (int r = 0; r < repeats; ++r) {
    double parts[2];
    const double t0 = now();
    forward(n, steps, dt, nuf, nu0, ut, w0, w1, w2);
    const double t1 = now();
    volatile double Jr = gradient(n, steps, dt, nuf, nu0, d, S, ut, g, w0, w1, w2, w3, parts);
    const double t2 = now();
    (void)Jr;
    tf[r] = t1 - t0, tg[r] = t2 - t1, ts[r] = parts[0], ta[r] = parts[1];
  }
  if (repeats > 0) {
    const double mf = median(tf, repeats), mg = median(tg, repeats);
    printf("timing: %d repeats, forward median %.6f s (min %.6f, max %.6f), gradient median %.6f s (min %.6f, max %.6f), "
           "gradient/forward %.3f\n",
           repeats, mf, tf[0], tf[repeats - 1], mg, tg[0], tg[repeats - 1], mg / mf);
    printf("timing: gradient parts, medians: forward solve storing the stages %.6f s, adjoint solve %.6f s\n",
           median(ts, repeats), median(ta, repeats));
  }
  printf("memory: stored stages %.1f MB\n", 4.0 * n * steps * sizeof(double) / 1e6);
  free(nu), free(d), free(ut), free(g), free(w), free(q), free(S), free(tf), free(tg), free(ts), free(ta);
  return 0;
}
