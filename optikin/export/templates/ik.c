/* ---- optikin export: the damped projected Gauss-Newton iteration (optikin.solvers.gauss_newton) ---- */
#include "${stem}.h"

#define NX ${PREFIX}_NFREE
#define NFULL ${PREFIX}_N
#define NR ${PREFIX}_M
#define NK ${PREFIX}_K

const double ${prefix}_start[NFULL] = {${start}};
static const int free_index[NX] = {${free_index}};   /* position of each solved variable in x */
static const double fixed_value[NFULL] = {${fixed_value}}; /* the value of each fixed variable (0: solved) */
static const double lower[NX] = {${lower}};
static const double upper[NX] = {${upper}};
static const double span[NX] = {${span}};
static const double lower_margin[NX] = {${lower_margin}}; /* lower + 1e-12 span */
static const double upper_margin[NX] = {${upper_margin}}; /* upper - 1e-12 span */
static const int periodic[NX] = {${periodic}};
static const double scaling[NX] = {${scaling}};            /* D = W^2 */
static const double tolerance = ${tolerance};               /* ||r|| counted as solved */
static const double stop_tolerance = ${stop_tolerance};     /* min(tolerance, the preset's) */
static const double stationarity_tolerance = ${stationarity_tolerance};
static const int exact = ${exact};
static const double damping = ${damping}, damping_min = ${damping_min}, damping_max = ${damping_max};
static const int max_calls = ${max_iterations};
static const int second_order = ${second_order};
static const double lambda_floor = ${lambda_floor};
static const double slow_progress = ${slow_progress};
static const int slow_steps = ${slow_steps};

void ${prefix}_init(${prefix}_work* work) {
  long i;
  for (i = 0; i < NK * NK; ++i) work->A[i] = 0.0;
  work->ready = 1;
}

/* Solve A y = b in place (b <- y), A k x k column-major, by LU with partial pivoting. */
static int lu_solve(double* A, double* b, int* pivot, int k) {
  int i, j, c, best;
  double t;
  for (c = 0; c < k; ++c) {
    best = c;
    for (i = c + 1; i < k; ++i)
      if (fabs(A[i + k * c]) > fabs(A[best + k * c])) best = i;
    pivot[c] = best;
    if (A[best + k * c] == 0.0) return 1;
    if (best != c) {
      for (j = 0; j < k; ++j) { t = A[c + k * j]; A[c + k * j] = A[best + k * j]; A[best + k * j] = t; }
      t = b[c]; b[c] = b[best]; b[best] = t;
    }
    for (i = c + 1; i < k; ++i) {
      t = A[i + k * c] / A[c + k * c];
      if (t != 0.0) {
        for (j = c + 1; j < k; ++j) A[i + k * j] -= t * A[c + k * j];
        b[i] -= t * b[c];
      }
    }
  }
  for (i = k - 1; i >= 0; --i) {
    t = b[i];
    for (j = i + 1; j < k; ++j) t -= A[i + k * j] * b[j];
    b[i] = t / A[i + k * i];
  }
  return 0;
}

/* The step direction with the variables free_ (1) or frozen (0): the module docstring of
   optikin.solvers.gauss_newton; the m x m form for Gauss-Newton with fewer residuals than variables. */
static void direction(${prefix}_work* w, int newton, double lam) {
  int i, j, k;
  double s;
  if (!newton && NR < NX) {
    for (i = 0; i < NR; ++i)
      for (j = 0; j < NR; ++j) {
        s = 0.0;
        for (k = 0; k < NX; ++k) s += w->J[i + NR * k] * (w->free_[k] / scaling[k]) * w->J[j + NR * k];
        w->A[i + NR * j] = s + (i == j ? lam : 0.0);
      }
    for (i = 0; i < NR; ++i) w->b[i] = w->r[i];
    lu_solve(w->A, w->b, w->pivot, NR);
    for (k = 0; k < NX; ++k) {
      s = 0.0;
      for (i = 0; i < NR; ++i) s += w->J[i + NR * k] * w->b[i];
      w->d[k] = -(w->free_[k] / scaling[k]) * s;
    }
    return;
  }
  for (i = 0; i < NX; ++i)
    for (j = 0; j < NX; ++j)
      w->A[i + NX * j] = w->free_[i] * w->H[i + NX * j] * w->free_[j] +
                         (i == j ? (1.0 - w->free_[i]) + lam * scaling[i] : 0.0);
  for (i = 0; i < NX; ++i) w->b[i] = w->free_[i] * w->g[i];
  lu_solve(w->A, w->b, w->pivot, NX);
  for (i = 0; i < NX; ++i) w->d[i] = -w->free_[i] * w->b[i];
}

/* One step from x: x_new, returns ||r(x)||, *stationarity of x (the step Function of gauss_newton). */
static double step(${prefix}_work* w, const double* x, const double* p, double mu, int newton, double* x_new,
                   double* stationarity) {
  int i, j, la, ua, blocked, any_blocked = 0;
  double rn = 0.0, trace = 0.0, fro = 0.0, gs = 0.0, lam, s, moved;
  w->arg[0] = x;
  w->arg[1] = p;
  w->res[0] = w->r;
  w->res[1] = w->J;
  ${prefix}_rj(w->arg, w->res, w->iw, w->w, 0);
  for (i = 0; i < NR; ++i) rn += w->r[i] * w->r[i];
  rn = sqrt(rn);
  for (j = 0; j < NX; ++j) {
    s = 0.0;
    w->g[j] = 0.0;
    for (i = 0; i < NR; ++i) {
      s += w->J[i + NR * j] * w->J[i + NR * j];
      w->g[j] += w->J[i + NR * j] * w->r[i];
    }
    fro += s;
    trace += s / scaling[j];
  }
  lam = mu * rn * rn + lambda_floor * trace / NR;
  if (newton) {
    w->res[0] = w->H;
    ${prefix}_hess(w->arg, w->res, w->iw, w->w, 0);
  } else if (NR >= NX) {
    for (i = 0; i < NX; ++i)
      for (j = i; j < NX; ++j) { /* J^T J is symmetric: each product J_li J_lj, summed in the same order */
        s = 0.0;
        for (la = 0; la < NR; ++la) s += w->J[la + NR * i] * w->J[la + NR * j];
        w->H[i + NX * j] = w->H[j + NX * i] = s;
      }
  }
  for (i = 0; i < NX; ++i) w->free_[i] = 1.0;
  direction(w, newton, lam);
  for (i = 0; i < NX; ++i) {
    la = !periodic[i] && x[i] <= lower_margin[i];
    ua = !periodic[i] && x[i] >= upper_margin[i];
    blocked = (la && w->d[i] < 0) || (ua && w->d[i] > 0);
    any_blocked |= blocked;
    w->free_[i] = 1.0 - blocked;
    if (!((la && w->g[i] > 0) || (ua && w->g[i] < 0))) gs += w->g[i] * w->g[i];
  }
  if (any_blocked) direction(w, newton, lam); /* else the restricted step is the one just computed */
  for (i = 0; i < NX; ++i) {
    moved = x[i] + w->d[i];
    if (periodic[i])
      x_new[i] = moved - span[i] * floor((moved - lower[i]) / span[i]);
    else
      x_new[i] = fmin(fmax(moved, lower[i]), upper[i]);
  }
  *stationarity = sqrt(gs) / (sqrt(fro) * rn + 1e-300);
  return rn;
}

static void copy(double* to, const double* from) {
  int i;
  for (i = 0; i < NX; ++i) to[i] = from[i];
}

int ${prefix}_solve(${prefix}_work* w, const double* x0, const double* p, double* x_out, double* residual,
                    int* iterations) {
  int i, calls, slow = 0, newton = 0;
  double mu = damping, trial_mu, rn, st, trial_rn, trial_st, t;
  if (!w || !p || !x_out || !w->ready) return ${PREFIX}_INVALID_INPUT;
  if (!x0) x0 = ${prefix}_start;
  for (i = 0; i < NFULL; ++i)
    if (!isfinite(x0[i])) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < ${PREFIX}_NP; ++i)
    if (!isfinite(p[i])) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < NX; ++i) { /* the solved variables of the start, projected into the box */
    t = x0[free_index[i]];
    if (periodic[i] && !(t >= lower[i] && t <= upper[i])) {
      t = fmod(t - lower[i], span[i]);
      w->x[i] = lower[i] + (t < 0 ? t + span[i] : t);
    } else {
      w->x[i] = periodic[i] ? t : fmin(fmax(t, lower[i]), upper[i]);
    }
  }
  rn = step(w, w->x, p, mu, newton, w->proposal, &st);
  calls = 1;
  while (calls < max_calls) {
    if (!(rn > stop_tolerance) || st <= stationarity_tolerance || mu > damping_max) break;
    trial_mu = fmax(mu * 0.1, damping_min);
    trial_rn = step(w, w->proposal, p, trial_mu, newton, w->next, &trial_st);
    calls += 1;
    if (trial_rn < rn || trial_rn <= stop_tolerance) {
      slow = trial_rn > slow_progress * rn ? slow + 1 : 0;
      if (slow >= slow_steps && !newton && second_order) newton = 1;
      copy(w->x, w->proposal);
      copy(w->proposal, w->next);
      mu = trial_mu;
      rn = trial_rn;
      st = trial_st;
    } else if (calls < max_calls) {
      mu *= 10.0;
      rn = step(w, w->x, p, mu, newton, w->proposal, &st);
      calls += 1;
    }
  }
  for (i = 0; i < NFULL; ++i) x_out[i] = fixed_value[i];
  for (i = 0; i < NX; ++i) x_out[free_index[i]] = w->x[i];
  if (residual) *residual = rn;
  if (iterations) *iterations = calls;
  if (!isfinite(rn)) return ${PREFIX}_FAILED;
  if (rn <= tolerance) return ${PREFIX}_OK;
  if (st <= stationarity_tolerance) return exact ? ${PREFIX}_UNREACHABLE : ${PREFIX}_OK;
  return ${PREFIX}_NOT_CONVERGED;
}

long ${prefix}_trajectory(${prefix}_work* w, const double* x0, const double* P, long n, double* X,
                          double* residuals, int* status, int* iterations) {
  long k, failures = 0;
  int s, i, finite, calls;
  double rn;
  const double* start = x0 ? x0 : ${prefix}_start;
  for (k = 0; k < n; ++k) {
    rn = NAN;
    calls = 0;
    s = ${prefix}_solve(w, start, P + k * ${PREFIX}_NP, X + k * NFULL, &rn, &calls);
    if (residuals) residuals[k] = rn;
    if (status) status[k] = s;
    if (iterations) iterations[k] = calls;
    if (s != ${PREFIX}_OK) failures += 1;
    finite = s != ${PREFIX}_INVALID_INPUT;
    for (i = 0; i < NFULL && finite; ++i) finite = isfinite(X[k * NFULL + i]);
    if (finite) start = X + k * NFULL;
  }
  return failures;
}
