/* The machine's memory bandwidth on one thread, STREAM-like, as the bound for memory-bound stencil
 * loops (run/bench_throughput.sh):
 *   copy   a[i] = b[i]          16 bytes per element (read b, write a)
 *   triad  a[i] = b[i] + s c[i] 24 bytes per element (read b and c, write a)
 * over arrays of N doubles each (default 2^25, 268 MB an array: far beyond any cache). Write-allocate
 * traffic (reading a's lines before writing them) is not counted, as in STREAM. The compiler may make
 * the copy loop a memcpy call, which can bypass the cache on large arrays (no write-allocate).
 * A leapfrog update moves at least 32 bytes per point (reads u_k, u_{k-1} and c, writes u_{k+1}; the
 * stencil's neighbours come from cache), so triad bandwidth / 32 B bounds the point-updates per second
 * of a forward step from memory (both counts leave out the write-allocate). Loops whose levels fit in
 * the last-level cache can pass it.
 *
 *   cc -O3 -o /tmp/stream_triad run/stream_triad.c
 *   /tmp/stream_triad [N=33554432] [repeats=10]
 * prints the best and the median bandwidth of both in GB/s (1e9 bytes) and the bound.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime under -std=c99 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "reference_common.h"

static double median(double *t, int m) {
  qsort(t, m, sizeof(double), cmp);
  return m % 2 ? t[m / 2] : 0.5 * (t[m / 2 - 1] + t[m / 2]);
}

int main(int argc, char **argv) {
  const long N = argc > 1 ? atol(argv[1]) : 1L << 25;
  const int repeats = argc > 2 && atoi(argv[2]) > 0 ? atoi(argv[2]) : 10;
  double *a = malloc(sizeof(double) * N), *b = malloc(sizeof(double) * N), *c = malloc(sizeof(double) * N);
  double *tc = malloc(sizeof(double) * repeats), *tt = malloc(sizeof(double) * repeats);
  if (N < 1 || !a || !b || !c || !tc || !tt) {
    fprintf(stderr, "stream_triad: N >= 1 and 3 N doubles of memory needed\n");
    return 1;
  }
  /* touched before timing, so that no page fault lands in a timed loop */
  for (long i = 0; i < N; ++i) a[i] = 0, b[i] = 1, c[i] = 2;
  const double s = 3;
  for (int r = 0; r < repeats; ++r) {
    double t0 = now();
    for (long i = 0; i < N; ++i) a[i] = b[i];
    tc[r] = now() - t0;
    t0 = now();
    for (long i = 0; i < N; ++i) a[i] = b[i] + s * c[i];
    tt[r] = now() - t0;
  }
  /* the result is read, so that the loops cannot be dropped */
  double check = 0;
  for (long i = 0; i < N; i += 4096) check += a[i];
  if (check != (double)((N + 4095) / 4096) * 7) fprintf(stderr, "stream_triad: unexpected result %g\n", check);
  const double copy_best = 16.0 * N / (qsort(tc, repeats, sizeof(double), cmp), tc[0]) / 1e9,
               copy_med = 16.0 * N / median(tc, repeats) / 1e9;
  const double triad_best = 24.0 * N / (qsort(tt, repeats, sizeof(double), cmp), tt[0]) / 1e9,
               triad_med = 24.0 * N / median(tt, repeats) / 1e9;
  printf("stream: N %ld doubles (%.0f MB an array), %d repeats, 1 thread\n", N, 8.0 * N / 1e6, repeats);
  printf("stream copy: best %.2f GB/s, median %.2f GB/s\n", copy_best, copy_med);
  printf("stream triad: best %.2f GB/s, median %.2f GB/s\n", triad_best, triad_med);
  printf("stream bound: triad median / 32 B = %.4e point-updates/s\n", triad_med * 1e9 / 32);
  free(a), free(b), free(c), free(tc), free(tt);
  return 0;
}
