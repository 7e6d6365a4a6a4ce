/* Example: ${prefix} on targets read from a file (or the ${n_samples} samples below), then a timing loop.

   usage: ./example [targets.txt [rounds]]   (one target per line, ${n_p} numbers)
   prints per target: status iterations ||r|| x[0..${n}-1]; then "per_call_us <wall microseconds per target>"
   and "cpu_us <process CPU microseconds per target>" on stderr, from repeating the whole set for 0.2 s
   (or `rounds` times; 0: no timing loop, e.g. to count instructions under valgrind).
   mode: ${mode} (independent: every target from the problem's start; trajectory: warm-started). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "${stem}.h"

#define MAX_TARGETS ${max_targets}
static const double samples[${n_samples}][${PREFIX}_NP] = {${samples}};
static double targets[MAX_TARGETS][${PREFIX}_NP];
static double X[MAX_TARGETS][${PREFIX}_N];
static double residuals[MAX_TARGETS];
static int status[MAX_TARGETS], iterations[MAX_TARGETS];
static const int trajectory = ${trajectory};

static void solve_all(${prefix}_work* work, long n) {
  long k;
  if (trajectory) {
    ${prefix}_trajectory(work, 0, &targets[0][0], n, &X[0][0], residuals, status, iterations);
    return;
  }
  for (k = 0; k < n; ++k) status[k] = ${prefix}_solve(work, 0, targets[k], X[k], &residuals[k], &iterations[k]);
}

int main(int argc, char** argv) {
  static ${prefix}_work work;
  long n = 0, k, rounds = 0, fixed_rounds = argc > 2 ? atol(argv[2]) : -1;
  int i;
  struct timespec t0, t1, c0, c1;
  double elapsed = 0.0;
  if (argc > 1) {
    FILE* f = fopen(argv[1], "r");
    if (!f) { perror(argv[1]); return 2; }
    while (n < MAX_TARGETS) {
      for (i = 0; i < ${PREFIX}_NP; ++i)
        if (fscanf(f, "%lf", &targets[n][i]) != 1) break;
      if (i < ${PREFIX}_NP) break;
      ++n;
    }
    fclose(f);
  } else {
    for (n = 0; n < ${n_samples}; ++n)
      for (i = 0; i < ${PREFIX}_NP; ++i) targets[n][i] = samples[n][i];
  }
  ${prefix}_init(&work);
  solve_all(&work, n);
  for (k = 0; k < n; ++k) {
    printf("%d %d %.17g", status[k], iterations[k], residuals[k]);
    for (i = 0; i < ${PREFIX}_N; ++i) printf(" %.17g", X[k][i]);
    printf("\n");
  }
  clock_gettime(CLOCK_MONOTONIC, &t0);
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
  while (n > 0 && (fixed_rounds < 0 ? elapsed < 0.2 : rounds < fixed_rounds)) {
    solve_all(&work, n);
    ++rounds;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    elapsed = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
  }
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c1);
  if (rounds) {
    fprintf(stderr, "per_call_us %.3f\n", 1e6 * elapsed / (rounds * n));
    fprintf(stderr, "cpu_us %.3f\n", ((c1.tv_sec - c0.tv_sec) * 1e6 + 1e-3 * (c1.tv_nsec - c0.tv_nsec)) / (rounds * n));
  }
  return 0;
}
