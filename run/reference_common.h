/* Shared by the hand-written reference loops (reference_*.c, leapfrog_layouts.c): a monotonic clock
   and the comparison qsort needs for medians. */
#ifndef FLEXIPDE_REFERENCE_COMMON_H
#define FLEXIPDE_REFERENCE_COMMON_H
#include <time.h>

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}
#endif
