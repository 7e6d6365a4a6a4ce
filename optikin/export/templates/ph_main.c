/* Example: ${prefix}_trajectory on samples read from a file (or the ${n_samples} samples below), then a timing loop.

   usage: ./example [samples.txt [max_iterations restart basin_check [seconds]]]
          (one sample per line: the ${n_p} entries of P, see ${stem}.h; the options override the preset's;
          seconds: length of the timing loop, 0.2 unless given, 0 for none)
   prints per sample: status iterations E S phi0 phi2; then, after the timing loop, "per_call_us <wall
   microseconds per sample>" and "cpu_us <process CPU microseconds per sample>" on stderr. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "${stem}.h"

#define MAX_SAMPLES ${max_samples}
static const double samples[${n_samples}][${PREFIX}_NP] = {${samples}};
static double P[MAX_SAMPLES][${PREFIX}_NP];
static double X[MAX_SAMPLES][${PREFIX}_NX];
static double ES[MAX_SAMPLES][2];
static int status[MAX_SAMPLES], iterations[MAX_SAMPLES];

int main(int argc, char** argv) {
  static ${prefix}_work work;
  long n = 0, k, rounds = 0;
  int i;
  struct timespec t0, t1, c0, c1;
  double elapsed = 0.0, seconds = 0.2;
  if (argc > 1) {
    FILE* f = fopen(argv[1], "r");
    if (!f) { perror(argv[1]); return 2; }
    while (n < MAX_SAMPLES) {
      for (i = 0; i < ${PREFIX}_NP; ++i)
        if (fscanf(f, "%lf", &P[n][i]) != 1) break;
      if (i < ${PREFIX}_NP) break;
      ++n;
    }
    fclose(f);
  } else {
    for (n = 0; n < ${n_samples}; ++n)
      for (i = 0; i < ${PREFIX}_NP; ++i) P[n][i] = samples[n][i];
  }
  ${prefix}_init(&work);
  if (argc > 4) {
    work.max_iterations = atoi(argv[2]);
    work.restart = atoi(argv[3]);
    work.basin_check = atoi(argv[4]);
  }
  if (argc > 5) seconds = atof(argv[5]);
  ${prefix}_trajectory(&work, &P[0][0], n, &X[0][0], &ES[0][0], iterations, status);
  for (k = 0; k < n; ++k)
    printf("%d %d %.17g %.17g %.17g %.17g\n", status[k], iterations[k], ES[k][0], ES[k][1], X[k][0], X[k][1]);
  clock_gettime(CLOCK_MONOTONIC, &t0);
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
  while (n > 0 && elapsed < seconds) {
    ${prefix}_trajectory(&work, &P[0][0], n, &X[0][0], &ES[0][0], iterations, status);
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
