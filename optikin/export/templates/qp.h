/* ${stem}.h: one tracking QP step of optikin problem ${problem} (${arm}), exported by `optikin export`.

   The step of optikin.control.qp.QPController (Seleem et al. 2020, eqs. 33-34, under limits):

     min_qdot  ||J(q) qdot - v||^2 + lambda ||qdot||^2,   v = xdot_ref + K (x_ref - x)
     s.t.      lb(q) <= qdot <= ub(q),   A qdot >= b   (rows with b = -inf are inactive)

   with J the ${task} Jacobian (CasADi-generated with H = J'J + lambda I and g = -J'v${flip_note}),
   K = diag(${gain_note}) [1/s], lambda = ${damping}, and the rate box of optikin.control.limits.RateBounds
   at control period dt = ${dt} s: lb = min(max(${limit_gain} (lower - q)/dt, -r), r),
   ub = min(max(${limit_gain} (upper - q)/dt, -r), r), r the rate limits${periodic_note}.
   The QP is solved exactly (no iteration tolerance: the optimum of the final active set): with the box
   alone by the primal active-set method (Nocedal and Wright 2006, Algorithm 16.3) from the unconstrained
   step clipped into the box, with rows (or should that not finish) by the dual active-set method of
   Goldfarb and Idnani (1983) on the Cholesky factor of H, constraints met to ${primal_tolerance} (1 + |bound|). The command is the solution clipped into the box (a no-op for the
   exact solution); where the QP has no solution, the controller's fallback (${fallback}): ${fallback_note}.

   Sizes (compile-time constants):
     ${PREFIX}_N         rates qdot and configuration q   (${n}: ${variables}; SI units, m/s and rad/s)
     ${PREFIX}_M         task entries x, x_ref, xdot_ref   (${m}: ${task_note})
     ${PREFIX}_MAX_ROWS  rows A qdot >= b a call may pass (${max_rows}), A row-major rows x N

   Memory: every array lives in ${prefix}_work, which the caller allocates (statically, on the
   stack or once at start-up) and prepares with ${prefix}_init. Nothing is allocated by the
   library. A work structure serves one thread at a time; A and b are read during the call only.

   Status codes (enum ${prefix}_status); qdot is always written:
     ${PREFIX}_OK             the QP's solution
     ${PREFIX}_INFEASIBLE     the rows contradict each other or the box (the dual is unbounded): fallback
     ${PREFIX}_NOT_CONVERGED  the dual method's limit of 10 (N + rows) + 10 active-set changes was reached: fallback
     ${PREFIX}_INVALID_INPUT  a null pointer, rows outside [0, MAX_ROWS], a non-finite q, x, x_ref,
                              xdot_ref or A, a NaN or +inf in b: qdot = 0
     ${PREFIX}_FAILED         H not positive definite or a non-finite solution: fallback
*/
#ifndef ${PREFIX}_H
#define ${PREFIX}_H

#ifdef __cplusplus
extern "C" {
#endif

#define ${PREFIX}_N ${n}
#define ${PREFIX}_M ${m}
#define ${PREFIX}_MAX_ROWS ${max_rows}

enum ${prefix}_status {
  ${PREFIX}_OK = 0,
  ${PREFIX}_INFEASIBLE = 1,
  ${PREFIX}_NOT_CONVERGED = 2,
  ${PREFIX}_INVALID_INPUT = 3,
  ${PREFIX}_FAILED = 4
};

/* Work arrays: sizes fixed at export; treat the fields as private. */
typedef struct {
  const double* arg[${sz_arg}];
  double* res[${sz_res}];
  long long iw[${sz_iw}];
  double w[${sz_w}];
  double H[${PREFIX}_N * ${PREFIX}_N]; /* J'J + lambda I, column-major */
  double g[${PREFIX}_N];               /* -J'v */
  double L[${PREFIX}_N * ${PREFIX}_N]; /* Cholesky factor of H */
  double lb[${PREFIX}_N];
  double ub[${PREFIX}_N];
  double x[${PREFIX}_N];
  double xu[${PREFIX}_N]; /* -H^-1 g, the unconstrained minimiser */
  double z[${PREFIX}_N];
  double vp[${PREFIX}_N];
  double V[${PREFIX}_N * ${PREFIX}_N]; /* H^-1 times each active constraint's normal */
  double Hinv[${PREFIX}_N * ${PREFIX}_N]; /* the columns of H^-1 computed so far this step */
  int have[${PREFIX}_N];
  double S[${PREFIX}_N * ${PREFIX}_N]; /* Cholesky factor of the active normals' matrix */
  double r[${PREFIX}_N];
  double u[${PREFIX}_N]; /* multipliers of the active constraints */
  int W[${PREFIX}_N];    /* the active constraints */
  int fixed[${PREFIX}_N];  /* polish: rates at an active bound, the free ones F, the active rows R */
  int F[${PREFIX}_N];
  int R[${PREFIX}_N];
  double P[${PREFIX}_N * ${PREFIX}_N];
  double Q[${PREFIX}_N * ${PREFIX}_N];
  double T[${PREFIX}_N * ${PREFIX}_N];
  double y[${PREFIX}_N];
  double lam[${PREFIX}_N];
  int k;
  int factored; /* S is the factor of the current active set */
  int is_active[2 * ${PREFIX}_N + ${PREFIX}_MAX_ROWS];
  const double* A;
  const double* b;
  int ready;
} ${prefix}_work;

/* Prepare the work structure (no allocation). Call once before any step. */
void ${prefix}_init(${prefix}_work* work);

/* One control step: measured configuration q (N) and task value x (M), reference x_ref (M) and its rate
   xdot_ref (M), rows rows of A qdot >= b (A rows x N row-major, b rows; both may be NULL when rows = 0).
   Writes the commanded rates into qdot (N) and the active-set changes into *iterations (may be NULL).
   Returns an enum ${prefix}_status. */
int ${prefix}_step(${prefix}_work* work, const double* q, const double* x, const double* x_ref, const double* xdot_ref,
                   const double* A, const double* b, int rows, double* qdot, int* iterations);

#ifdef __cplusplus
}
#endif
#endif
