/* Example: ${prefix} on configurations read from a file (or the ${n_samples} samples below), then a timing loop.

   usage: ./example [configurations.txt]   (one configuration per line, ${n} numbers)
   prints per configuration and function: "<name> <status> <values...>"; then, on stderr,
   "per_call_us <name> <microseconds>" for each function. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "${stem}.h"

#define MAX_SAMPLES ${max_targets}
static const double samples[${n_samples}][${PREFIX}_N] = {${samples}};
static double Q[MAX_SAMPLES][${PREFIX}_N];
static double out[${max_out}];

typedef int (*fk_function)(${prefix}_work*, const double*, double*);
static const fk_function functions[] = {${function_list}};
static const char* names[] = {${name_list}};
static const int sizes[] = {${size_list}};

int main(int argc, char** argv) {
  static ${prefix}_work work;
  long n = 0, k, rounds;
  int i, f, s;
  struct timespec t0, t1;
  double elapsed;
  if (argc > 1) {
    FILE* file = fopen(argv[1], "r");
    if (!file) { perror(argv[1]); return 2; }
    while (n < MAX_SAMPLES) {
      for (i = 0; i < ${PREFIX}_N; ++i)
        if (fscanf(file, "%lf", &Q[n][i]) != 1) break;
      if (i < ${PREFIX}_N) break;
      ++n;
    }
    fclose(file);
  } else {
    for (n = 0; n < ${n_samples}; ++n)
      for (i = 0; i < ${PREFIX}_N; ++i) Q[n][i] = samples[n][i];
  }
  ${prefix}_init(&work);
  for (k = 0; k < n; ++k)
    for (f = 0; f < ${n_functions}; ++f) {
      s = functions[f](&work, Q[k], out);
      printf("%s %d", names[f], s);
      for (i = 0; i < sizes[f]; ++i) printf(" %.17g", out[i]);
      printf("\n");
    }
  for (f = 0; f < ${n_functions} && n > 0; ++f) {
    rounds = 0;
    elapsed = 0.0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    while (elapsed < 0.1) {
      for (k = 0; k < n; ++k) functions[f](&work, Q[k], out);
      ++rounds;
      clock_gettime(CLOCK_MONOTONIC, &t1);
      elapsed = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    }
    fprintf(stderr, "per_call_us %s %.4f\n", names[f], 1e6 * elapsed / (rounds * n));
  }
  return 0;
}
