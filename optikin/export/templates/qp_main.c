/* Example: ${prefix}_step on steps read from a file (or the ${n_samples} steps below), then a timing loop.

   usage: ./example [steps.txt]
     one step per line: q (${n}) x (${m}) x_ref (${m}) xdot_ref (${m}) rows, then rows times (a (${n}) b)
   prints per step: status iterations qdot[0..${n}-1]; then "per_call_us <wall microseconds per step>"
   and "cpu_us <process CPU microseconds per step>" on stderr. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "${stem}.h"

#define N ${PREFIX}_N
#define M ${PREFIX}_M
#define MAX_STEPS ${max_samples}
#define WIDTH (N + 3 * M)
static const double samples[${n_samples}][WIDTH] = {${samples}};
static double steps[MAX_STEPS][WIDTH];
static double A[MAX_STEPS][${PREFIX}_MAX_ROWS * N];
static double b[MAX_STEPS][${PREFIX}_MAX_ROWS];
static int rows[MAX_STEPS];
static double qdot[MAX_STEPS][N];
static int status[MAX_STEPS], iterations[MAX_STEPS];

static void run(${prefix}_work* work, long n) {
  long k;
  for (k = 0; k < n; ++k) {
    const double* s = steps[k];
    status[k] = ${prefix}_step(work, s, s + N, s + N + M, s + N + 2 * M, A[k], b[k], rows[k], qdot[k], &iterations[k]);
  }
}

static int read_steps(const char* name, long* n) {
  int i, j;
  FILE* f = fopen(name, "r");
  if (!f) { perror(name); return 1; }
  for (*n = 0; *n < MAX_STEPS; ++*n) {
    for (i = 0; i < WIDTH; ++i)
      if (fscanf(f, "%lf", &steps[*n][i]) != 1) break;
    if (i < WIDTH || fscanf(f, "%d", &rows[*n]) != 1) break;
    if (rows[*n] < 0 || rows[*n] > ${PREFIX}_MAX_ROWS) { fprintf(stderr, "line %ld: bad row count\n", *n + 1); return 1; }
    for (j = 0; j < rows[*n]; ++j) {
      for (i = 0; i < N; ++i)
        if (fscanf(f, "%lf", &A[*n][j * N + i]) != 1) return 1;
      if (fscanf(f, "%lf", &b[*n][j]) != 1) return 1;
    }
  }
  fclose(f);
  return 0;
}

int main(int argc, char** argv) {
  static ${prefix}_work work;
  long n = 0, k, rounds = 0;
  int i;
  struct timespec t0, t1, c0, c1;
  double elapsed = 0.0;
  if (argc > 1) {
    if (read_steps(argv[1], &n)) return 2;
  } else {
    for (n = 0; n < ${n_samples}; ++n)
      for (i = 0; i < WIDTH; ++i) steps[n][i] = samples[n][i];
  }
  ${prefix}_init(&work);
  run(&work, n);
  for (k = 0; k < n; ++k) {
    printf("%d %d", status[k], iterations[k]);
    for (i = 0; i < N; ++i) printf(" %.17g", qdot[k][i]);
    printf("\n");
  }
  clock_gettime(CLOCK_MONOTONIC, &t0);
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
  while (n > 0 && elapsed < 0.2) {
    run(&work, n);
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
