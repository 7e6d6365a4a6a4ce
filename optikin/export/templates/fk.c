/* ---- optikin export: checked entry points of the generated forward kinematics ---- */
#include "${stem}.h"

void ${prefix}_init(${prefix}_work* work) { (void)work; }

static int evaluate(int (*f)(const casadi_real**, casadi_real**, casadi_int*, casadi_real*, int), ${prefix}_work* w,
                    const double* q, double* out) {
  int i;
  if (!w || !q || !out) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < ${PREFIX}_N; ++i)
    if (!isfinite(q[i])) return ${PREFIX}_INVALID_INPUT;
  w->arg[0] = q;
  w->res[0] = out;
  return f(w->arg, w->res, w->iw, w->w, 0) ? ${PREFIX}_FAILED : ${PREFIX}_OK;
}

${definitions}
