/* ---- optikin export: one tracking QP step (optikin.control.qp), solved by a dense dual active-set method ---- */
#include "${stem}.h"

#define N ${PREFIX}_N
#define M ${PREFIX}_M
#define NROWS ${PREFIX}_MAX_ROWS

static const double gain[M] = {${gain}};           /* K = diag(gain) [1/s] */
static const double damping[1] = {${damping}};     /* lambda */
static const double lower[N] = {${lower}};         /* configuration limits less the margin (periodic: unused) */
static const double upper[N] = {${upper}};
static const double rate[N] = {${rate}};           /* rate limits */
static const int periodic[N] = {${periodic}};
static const double dt = ${dt};                    /* control period [s] */
static const double limit_gain = ${limit_gain};    /* fraction of the distance to a limit one step may cover */
static const int fallback_dls = ${fallback_dls};   /* 0: hold, 1: damped least squares */
static const double primal_tolerance = ${primal_tolerance};
static const double rounding = ${rounding}; /* a dependent constraint violated by less is taken as met */

void ${prefix}_init(${prefix}_work* work) { work->ready = 1; }

/* A <- its Cholesky factor L (A = L L', n x n, lower triangle, column-major with leading dimension N);
   1 when A is not positive definite. */
static int factor(double* A, int n) {
  int i, j, k;
  double s;
  for (j = 0; j < n; ++j) {
    s = A[j + N * j];
    for (k = 0; k < j; ++k) s -= A[j + N * k] * A[j + N * k];
    if (!(s > 0)) return 1;
    A[j + N * j] = sqrt(s);
    for (i = j + 1; i < n; ++i) {
      s = A[i + N * j];
      for (k = 0; k < j; ++k) s -= A[i + N * k] * A[j + N * k];
      A[i + N * j] = s / A[j + N * j];
    }
  }
  return 0;
}

/* y <- (L L')^-1 y with the factor of factor(). */
static void factor_solve(const double* L, int n, double* y) {
  int i, k;
  double s;
  for (i = 0; i < n; ++i) {
    s = y[i];
    for (k = 0; k < i; ++k) s -= L[i + N * k] * y[k];
    y[i] = s / L[i + N * i];
  }
  for (i = n - 1; i >= 0; --i) {
    s = y[i];
    for (k = i + 1; k < n; ++k) s -= L[k + N * i] * y[k];
    y[i] = s / L[i + N * i];
  }
}

/* L <- the Cholesky factor of H. */
static int cholesky(const double* H, double* L) {
  int i;
  for (i = 0; i < N * N; ++i) L[i] = H[i];
  return factor(L, N);
}

/* Constraint j >= 0 reads c_j' qdot >= d_j: j < N lower bound of rate j, j < 2N upper bound (-e_j' qdot >= -ub_j),
   then the rows A qdot >= b. */
static double normal_dot(const ${prefix}_work* w, int j, const double* y) {
  int i;
  double s = 0.0;
  if (j < N) return y[j];
  if (j < 2 * N) return -y[j - N];
  for (i = 0; i < N; ++i) s += w->A[(j - 2 * N) * N + i] * y[i];
  return s;
}

static double rhs(const ${prefix}_work* w, int j) {
  if (j < N) return w->lb[j];
  if (j < 2 * N) return -w->ub[j - N];
  return w->b[j - 2 * N];
}

static void normal(const ${prefix}_work* w, int j, double* y) {
  int i;
  for (i = 0; i < N; ++i) y[i] = 0.0;
  if (j < N)
    y[j] = 1.0;
  else if (j < 2 * N)
    y[j - N] = -1.0;
  else
    for (i = 0; i < N; ++i) y[i] = w->A[(j - 2 * N) * N + i];
}

/* S <- the Cholesky factor of N_W' H^-1 N_W (k x k), the active normals' matrix; 1 when not positive definite. */
static int active_factor(${prefix}_work* w) {
  int i, j;
  for (j = 0; j < w->k; ++j)
    for (i = j; i < w->k; ++i) w->S[i + N * j] = normal_dot(w, w->W[i], w->V + N * j);
  return factor(w->S, w->k);
}

/* v <- H^-1 c_j; for a bound, the column of H^-1 (each computed once per step). */
static void inverse_times_normal(${prefix}_work* w, int j, double* v) {
  int i, l, c = j % N;
  double s, sign = j < N ? 1.0 : -1.0, *column = w->Hinv + N * c;
  if (j >= 2 * N) {
    normal(w, j, v);
    factor_solve(w->L, N, v);
    return;
  }
  if (!w->have[c]) { /* L^-1 e_c is zero above c: the forward substitution starts there */
    for (i = 0; i < N; ++i) column[i] = 0.0;
    for (i = c; i < N; ++i) {
      s = i == c ? 1.0 : 0.0;
      for (l = c; l < i; ++l) s -= w->L[i + N * l] * column[l];
      column[i] = s / w->L[i + N * i];
    }
    for (i = N - 1; i >= 0; --i) {
      s = column[i];
      for (l = i + 1; l < N; ++l) s -= w->L[l + N * i] * column[l];
      column[i] = s / w->L[i + N * i];
    }
    w->have[c] = 1;
  }
  for (i = 0; i < N; ++i) v[i] = sign * column[i];
}

/* The factor S of the active set with c_p appended as its last constraint (v = H^-1 c_p): one new row. */
static void append(${prefix}_work* w, int p, const double* v) {
  int i, l, k = w->k;
  double s, d;
  if (!w->factored && k > 0) return;
  d = normal_dot(w, p, v);
  for (i = 0; i < k; ++i) {
    s = normal_dot(w, w->W[i], v);
    for (l = 0; l < i; ++l) s -= w->S[i + N * l] * w->S[k + N * l];
    s /= w->S[i + N * i];
    w->S[k + N * i] = s;
    d -= s * s;
  }
  if (d > 0) {
    w->S[k + N * k] = sqrt(d);
    w->factored = 1;
  } else {
    w->factored = 0;
  }
}

/* x, u <- the minimiser on the active set and its multipliers: x = x_u + H^-1 N_W u with N_W' x = d_W. */
static int refine(${prefix}_work* w) {
  int i, j;
  if (!w->factored && active_factor(w)) return 1;
  w->factored = 1;
  for (j = 0; j < w->k; ++j) w->u[j] = rhs(w, w->W[j]) - normal_dot(w, w->W[j], w->xu);
  factor_solve(w->S, w->k, w->u);
  for (i = 0; i < N; ++i) {
    w->x[i] = w->xu[i];
    for (j = 0; j < w->k; ++j) w->x[i] += w->V[i + N * j] * w->u[j];
  }
  for (j = 0; j < w->k; ++j) /* a rate at an active bound sits on it */
    if (w->W[j] < N)
      w->x[w->W[j]] = w->lb[w->W[j]];
    else if (w->W[j] < 2 * N)
      w->x[w->W[j] - N] = w->ub[w->W[j] - N];
  return 0;
}

static void drop(${prefix}_work* w, int l) {
  int i, j;
  w->factored = 0;
  w->is_active[w->W[l]] = 0;
  for (j = l; j + 1 < w->k; ++j) {
    w->W[j] = w->W[j + 1];
    w->u[j] = w->u[j + 1];
    for (i = 0; i < N; ++i) w->V[i + N * j] = w->V[i + N * (j + 1)];
  }
  w->k -= 1;
}

/* x <- the minimiser on the final active set from the reduced system: the rates at their bounds fixed,
   H_FF x_F = -(g_F + H_FB x_B) + A_RF' lam with A_RF x_F = b_R - A_RB x_B over the active rows R (more
   accurate than x_u + H^-1 N_W u when H is ill-conditioned). Left as it is when a system is singular. */
static void polish(${prefix}_work* w) {
  int i, j, a, c, nf = 0, nr = 0, *F = w->F, *R = w->R;
  double s, *P = w->P, *Q = w->Q, *T = w->T, *y = w->y, *lam = w->lam;
  for (i = 0; i < N; ++i) w->fixed[i] = 0;
  for (j = 0; j < w->k; ++j)
    if (w->W[j] < 2 * N)
      w->fixed[w->W[j] % N] = 1;
    else
      R[nr++] = w->W[j] - 2 * N;
  for (i = 0; i < N; ++i)
    if (!w->fixed[i]) F[nf++] = i;
  if (nf == 0) return;
  for (c = 0; c < nf; ++c)
    for (a = 0; a < nf; ++a) P[a + N * c] = w->H[F[a] + N * F[c]];
  if (factor(P, nf)) return;
  for (a = 0; a < nf; ++a) {
    s = -w->g[F[a]];
    for (i = 0; i < N; ++i)
      if (w->fixed[i]) s -= w->H[F[a] + N * i] * w->x[i];
    y[a] = s;
  }
  factor_solve(P, nf, y);
  if (nr) {
    for (c = 0; c < nr; ++c) {
      for (a = 0; a < nf; ++a) Q[a + N * c] = w->A[R[c] * N + F[a]];
      factor_solve(P, nf, Q + N * c);
    }
    for (c = 0; c < nr; ++c)
      for (a = c; a < nr; ++a) {
        s = 0.0;
        for (i = 0; i < nf; ++i) s += w->A[R[a] * N + F[i]] * Q[i + N * c];
        T[a + N * c] = s;
      }
    if (factor(T, nr)) return;
    for (c = 0; c < nr; ++c) {
      s = w->b[R[c]];
      for (i = 0; i < N; ++i)
        if (w->fixed[i]) s -= w->A[R[c] * N + i] * w->x[i];
      for (a = 0; a < nf; ++a) s -= w->A[R[c] * N + F[a]] * y[a];
      lam[c] = s;
    }
    factor_solve(T, nr, lam);
    for (a = 0; a < nf; ++a)
      for (c = 0; c < nr; ++c) y[a] += Q[a + N * c] * lam[c];
  }
  for (a = 0; a < nf; ++a) w->x[F[a]] = y[a];
}

/* min 1/2 x'Hx + g'x over the box only, by the primal active-set method (Nocedal and Wright 2006, Algorithm
   16.3) from the unconstrained minimiser clipped into the box: the free rates' reduced system solved, a step to
   the nearest bound it meets, a bound with a negative multiplier released. A rate with lb = ub stays on it.
   Returns ${PREFIX}_OK, or ${PREFIX}_NOT_CONVERGED after max_it changes (the dual method then takes over). */
static int box_active_set(${prefix}_work* w, int* iterations) {
  int i, a, c, nf, it, blocking, max_it = 4 * N + 10, *F = w->F, *state = w->fixed;
  double s, alpha, worst, scale = 0.0, *x = w->x, *y = w->y, *P = w->P;
  for (i = 0; i < N; ++i) {
    x[i] = w->xu[i];
    state[i] = w->lb[i] == w->ub[i] ? 2 : x[i] < w->lb[i] ? -1 : x[i] > w->ub[i] ? 1 : 0;
    if (state[i]) x[i] = state[i] > 0 ? w->ub[i] : w->lb[i];
    scale = fmax(scale, fabs(w->g[i]));
  }
  for (it = 0; it < max_it; ++it) {
    nf = 0;
    for (i = 0; i < N; ++i)
      if (!state[i]) F[nf++] = i;
    for (c = 0; c < nf; ++c) /* y <- the minimiser over the free rates, the others held */
      for (a = 0; a < nf; ++a) P[a + N * c] = w->H[F[a] + N * F[c]];
    if (nf && factor(P, nf)) return ${PREFIX}_FAILED;
    for (a = 0; a < nf; ++a) {
      s = -w->g[F[a]];
      for (i = 0; i < N; ++i)
        if (state[i]) s -= w->H[F[a] + N * i] * x[i];
      y[a] = s;
    }
    factor_solve(P, nf, y);
    alpha = 1.0;
    blocking = -1;
    for (a = 0; a < nf; ++a) {
      i = F[a];
      if (y[a] < w->lb[i] && (w->lb[i] - x[i]) / (y[a] - x[i]) < alpha) {
        alpha = (w->lb[i] - x[i]) / (y[a] - x[i]);
        blocking = i;
      } else if (y[a] > w->ub[i] && (w->ub[i] - x[i]) / (y[a] - x[i]) < alpha) {
        alpha = (w->ub[i] - x[i]) / (y[a] - x[i]);
        blocking = i;
      }
    }
    if (blocking >= 0) { /* a step to the bound met first, which joins the working set */
      for (a = 0; a < nf; ++a) x[F[a]] += alpha * (y[a] - x[F[a]]);
      for (a = 0; a < nf; ++a)
        if (F[a] == blocking) state[blocking] = y[a] < w->lb[blocking] ? -1 : 1;
      x[blocking] = state[blocking] > 0 ? w->ub[blocking] : w->lb[blocking];
      continue;
    }
    for (a = 0; a < nf; ++a) x[F[a]] = y[a];
    worst = -1e-13 * (1.0 + scale); /* the most negative multiplier of a bound, grad_i (lower) or -grad_i (upper) */
    c = -1;
    for (i = 0; i < N; ++i) {
      if (state[i] != 1 && state[i] != -1) continue;
      s = w->g[i];
      for (a = 0; a < N; ++a) s += w->H[i + N * a] * x[a];
      s *= state[i] < 0 ? 1.0 : -1.0;
      if (s < worst) {
        worst = s;
        c = i;
      }
    }
    if (c < 0) {
      *iterations = it;
      return ${PREFIX}_OK;
    }
    state[c] = 0;
  }
  *iterations = it;
  return ${PREFIX}_NOT_CONVERGED;
}

/* min 1/2 x'Hx + g'x over the constraints (Goldfarb and Idnani 1983, the dual method; the active set's normal
   matrix factor extended by a row when a constraint joins, re-factored after one leaves). Returns an enum ${prefix}_status; x in w->x. */
static int dual_active_set(${prefix}_work* w, int rows, int* iterations) {
  int i, j, p, l, it, nc = 2 * N + rows, max_it = 10 * (N + rows) + 10;
  double worst, s, t1, t2, t, rmax, zn, *x = w->x, *z = w->z, *v = w->vp;
  for (i = 0; i < N; ++i) x[i] = w->xu[i];
  for (j = 0; j < nc; ++j) w->is_active[j] = 0;
  for (i = 0; i < N; ++i) w->have[i] = 0;
  w->k = 0;
  w->factored = 0;
  for (it = 0; it < max_it; ++it) {
    p = -1;
    worst = 0.0;
    for (j = 0; j < nc; ++j) {
      if (w->is_active[j] || (j >= 2 * N && isinf(w->b[j - 2 * N]))) continue;
      s = normal_dot(w, j, x) - rhs(w, j);
      if (s < -primal_tolerance * (1.0 + fabs(rhs(w, j))) && s < worst) {
        worst = s;
        p = j;
      }
    }
    if (p < 0) {
      polish(w);
      *iterations = it;
      return ${PREFIX}_OK;
    }
    for (;;) { /* add p, dropping constraints whose multiplier would turn negative */
      if (++it > max_it) break;
      inverse_times_normal(w, p, v);
      if (w->k > 0) {
        if (!w->factored && active_factor(w)) return ${PREFIX}_FAILED;
        for (j = 0; j < w->k; ++j) w->r[j] = normal_dot(w, w->W[j], v);
        factor_solve(w->S, w->k, w->r);
      }
      for (i = 0; i < N; ++i) {
        s = v[i];
        for (l = 0; l < w->k; ++l) s -= w->V[i + N * l] * w->r[l];
        z[i] = s;
      }
      zn = normal_dot(w, p, z);
      l = -1;
      t1 = INFINITY;
      rmax = 0.0;
      for (j = 0; j < w->k; ++j) rmax = fmax(rmax, fabs(w->r[j]));
      for (j = 0; j < w->k; ++j)
        if (w->r[j] > 1e-12 * rmax && w->u[j] / w->r[j] < t1) {
          t1 = w->u[j] / w->r[j];
          l = j;
        }
      t2 = w->k < N && zn > 1e-10 * normal_dot(w, p, v) ? -(normal_dot(w, p, x) - rhs(w, p)) / zn : INFINITY;
      t = fmin(t1, t2);
      if (isinf(t)) {
        if (-(normal_dot(w, p, x) - rhs(w, p)) <= rounding * (1.0 + fabs(rhs(w, p)))) {
          w->is_active[p] = 2; /* met but for rounding, and dependent on the active set: left out */
          break;
        }
        *iterations = it;
        return ${PREFIX}_INFEASIBLE;
      }
      for (j = 0; j < w->k; ++j) w->u[j] -= t * w->r[j];
      if (isfinite(t2))
        for (i = 0; i < N; ++i) x[i] += t * z[i];
      if (t2 <= t1) { /* full step: p joins the active set; x, u recomputed from it (no drift from rounding) */
        append(w, p, v);
        w->W[w->k] = p;
        for (i = 0; i < N; ++i) w->V[i + N * w->k] = v[i];
        w->k += 1;
        w->is_active[p] = 1;
        if (refine(w)) return ${PREFIX}_FAILED;
        break;
      }
      drop(w, l);
    }
  }
  *iterations = it;
  return ${PREFIX}_NOT_CONVERGED;
}

int ${prefix}_step(${prefix}_work* w, const double* q, const double* x, const double* x_ref, const double* xdot_ref,
                   const double* A, const double* b, int rows, double* qdot, int* iterations) {
  int i, status, dls, active_rows, its = 0;
  double limit;
  if (!w || !w->ready || !q || !x || !x_ref || !xdot_ref || !qdot || rows < 0 || rows > NROWS || (rows && (!A || !b)))
    return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < N; ++i) qdot[i] = 0.0;
  if (iterations) *iterations = 0;
  for (i = 0; i < N; ++i)
    if (!isfinite(q[i])) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < M; ++i)
    if (!isfinite(x[i]) || !isfinite(x_ref[i]) || !isfinite(xdot_ref[i])) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < rows * N; ++i)
    if (!isfinite(A[i])) return ${PREFIX}_INVALID_INPUT;
  for (i = 0; i < rows; ++i)
    if (isnan(b[i]) || b[i] == INFINITY) return ${PREFIX}_INVALID_INPUT;
  w->A = A;
  w->b = b;
  for (i = 0; i < N; ++i) { /* optikin.control.limits.RateBounds */
    if (periodic[i]) {
      w->lb[i] = -rate[i];
      w->ub[i] = rate[i];
      continue;
    }
    limit = limit_gain * (lower[i] - q[i]) / dt;
    w->lb[i] = fmin(fmax(limit, -rate[i]), rate[i]);
    limit = limit_gain * (upper[i] - q[i]) / dt;
    w->ub[i] = fmin(fmax(limit, -rate[i]), rate[i]);
  }
  w->arg[0] = q;
  w->arg[1] = x;
  w->arg[2] = x_ref;
  w->arg[3] = xdot_ref;
  w->arg[4] = gain;
  w->arg[5] = damping;
  for (i = 0; i < 6; ++i) w->res[i] = 0;
  w->res[3] = w->H;
  w->res[5] = w->g;
  ${prefix}_task(w->arg, w->res, w->iw, w->w, 0);
  status = ${PREFIX}_FAILED;
  for (i = 0, active_rows = 0; i < rows; ++i) active_rows += !isinf(b[i]);
  if (!cholesky(w->H, w->L)) {
    for (i = 0; i < N; ++i) w->xu[i] = -w->g[i];
    factor_solve(w->L, N, w->xu);
    status = active_rows ? ${PREFIX}_NOT_CONVERGED : box_active_set(w, &its);
    if (status == ${PREFIX}_NOT_CONVERGED) status = dual_active_set(w, rows, &its);
  }
  if (iterations) *iterations = its;
  if (status == ${PREFIX}_OK)
    for (i = 0; i < N; ++i)
      if (!isfinite(w->x[i])) status = ${PREFIX}_FAILED;
  if (status != ${PREFIX}_OK) { /* the controller's fallback: hold, or the unconstrained step; into the box below */
    dls = fallback_dls && !cholesky(w->H, w->L);
    for (i = 0; i < N; ++i) w->x[i] = dls ? -w->g[i] : 0.0;
    if (dls) factor_solve(w->L, N, w->x);
  }
  for (i = 0; i < N; ++i) qdot[i] = fmin(fmax(w->x[i], w->lb[i]), w->ub[i]);
  return status;
}
