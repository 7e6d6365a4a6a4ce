/* ${stem}.h: forward kinematics of the arm of optikin problem ${problem} (${arm}), exported by `optikin export`.

   Input: the configuration q, ${PREFIX}_N = ${n} entries (${variables}).
   Outputs (column-major, CasADi's layout):
${output_list}
   Memory: every array lives in ${prefix}_work, which the caller allocates (statically, on the
   stack or once at start-up); nothing is allocated by the library. One thread per work structure.

   Status codes: ${PREFIX}_OK (0), ${PREFIX}_INVALID_INPUT (3: a null pointer or a non-finite entry of q),
   ${PREFIX}_FAILED (4: the evaluation failed). */
#ifndef ${PREFIX}_H
#define ${PREFIX}_H

#ifdef __cplusplus
extern "C" {
#endif

#define ${PREFIX}_N ${n}
${size_defines}
enum ${prefix}_status { ${PREFIX}_OK = 0, ${PREFIX}_INVALID_INPUT = 3, ${PREFIX}_FAILED = 4 };

/* Work arrays: sizes fixed at export; treat the fields as private. */
typedef struct {
  const double* arg[${sz_arg}];
  double* res[${sz_res}];
  long long iw[${sz_iw}];
  double w[${sz_w}];
} ${prefix}_work;

/* Nothing to prepare beyond the structure itself; kept for a uniform API. */
void ${prefix}_init(${prefix}_work* work);

${declarations}
#ifdef __cplusplus
}
#endif
#endif
