/* ---- optikin export: minimum-energy PH quintic along a trajectory (optikin.curves.min_energy, newton) ---- */
#include "${stem}.h"

#define NX ${PREFIX}_NX
#define NP ${PREFIX}_NP
#define NOUT 7 /* E, S, max|g|, lambda_min(H), step p (2), g.p */

static const double energy_noise = ${energy_noise}; /* a trial raising E by less is accepted */
static const double prediction_safety = ${prediction_safety};
static const double curvature_safety = ${curvature_safety};
static const double two_pi = 6.283185307179586;
static const double pi = 3.141592653589793;

void ${prefix}_init(${prefix}_work* work) {
  work->tolerance = ${tolerance};
  work->max_iterations = ${max_iterations};
  work->warm_start = ${warm_start};
  work->restart = ${restart};
  work->basin_check = ${basin_check};
  work->now = work->buffers[0];
  work->trial = work->buffers[1];
  work->ready = 1;
}

/* Python's float (a + pi) % (2 pi) - pi: the remainder takes the sign of the divisor. */
static double wrap(double a) {
  double m = fmod(a + pi, two_pi);
  if (m != 0.0) {
    if (m < 0.0) m += two_pi;
  } else {
    m = 0.0;
  }
  return m - pi;
}

${grid_energy}
/* out <- [E, S, max|g|, lambda_min, p0, p1, g.p] at x (newton.modified_newton_outputs) of the sample's family. */
static void evaluate(${prefix}_work* w, const double* x, double* out) {
  w->arg[0] = x;
  w->arg[1] = w->family;
  w->res[0] = out;
  ${prefix}_newton(w->arg, w->res, w->iw, w->w, 0);
}

/* out <- [E, S, max|g|] at x (the first three entries of evaluate's, by the same operations). */
static void evaluate_gradient(${prefix}_work* w, const double* x, double* out) {
  w->arg[0] = x;
  w->arg[1] = w->family;
  w->res[0] = out;
  ${prefix}_gradient(w->arg, w->res, w->iw, w->w, 0);
}

/* newton.converging_step: the next full step is predicted to meet the tolerance (quadratic convergence). */
static int converging_step(double gmax, double lmin, double step, double previous, double tol, double E) {
  double rho;
  if (!(previous > 0)) return 0;
  rho = gmax / (previous * previous);
  return rho * step * step <= prediction_safety * tol * (1.0 + fabs(E)) && lmin > curvature_safety * rho * step;
}

/* Modified Newton from x (in place): Armijo backtracking on E, as newton.modified_newton. Returns 1 when
   converged; *E, *S of the last iterate, *iterations the Newton steps taken. A full step predicted to
   converge is evaluated without the Hessian (evaluate_gradient); where it does not converge after all,
   the full evaluation follows. */
static int newton(${prefix}_work* w, double* x, double* E, double* S, int* iterations) {
  int it, k, accepted, predicted = 0;
  double step, noise, size, previous = 0.0, *now = w->now, *trial = w->trial, *t;
  evaluate(w, x, now);
  for (it = 0; it <= w->max_iterations; ++it) {
    if (now[2] <= w->tolerance * (1.0 + fabs(now[0])) && (predicted || now[3] > 0)) {
      *E = now[0];
      *S = now[1];
      *iterations = it;
      return 1;
    }
    if (it == w->max_iterations) break;
    if (predicted) evaluate(w, x, now);
    size = fabs(now[5]) > fabs(now[4]) ? fabs(now[5]) : fabs(now[4]); /* Python's max(|p0|, |p1|) */
    predicted = converging_step(now[2], now[3], size, previous, w->tolerance, now[0]);
    noise = energy_noise * (1.0 + fabs(now[0]));
    step = 1.0;
    accepted = 0;
    for (k = 0; k < 30; ++k) {
      w->xt[0] = x[0] + step * now[4];
      w->xt[1] = x[1] + step * now[5];
      if (predicted)
        evaluate_gradient(w, w->xt, trial);
      else
        evaluate(w, w->xt, trial);
      if (trial[0] <= now[0] + 1e-4 * step * now[6] + noise) {
        accepted = 1;
        break;
      }
      step *= 0.5;
      predicted = 0;
    }
    if (!accepted) break;
    previous = step * size;
    x[0] = x[0] + step * now[4];
    x[1] = x[1] + step * now[5];
    t = now;
    now = trial;
    trial = t;
  }
  *E = now[0];
  *S = now[1];
  *iterations = it;
  return 0;
}

/* The best point of the coarse angle grid (energy at the grid's phi0-major order; the first lowest kept). */
static void coarse_start(${prefix}_work* w, double* x) {
  int k;
  double best = INFINITY;
  const int n = ${coarse_grid};
  x[0] = -pi;
  x[1] = -pi;
  ${prefix}_grid_energy(w->family, w->grid);
  for (k = 0; k < n * n; ++k)
    if (isfinite(w->grid[k]) && w->grid[k] < best) {
      best = w->grid[k];
      x[0] = -pi + two_pi * (k / n) / n;
      x[1] = -pi + two_pi * (k % n) / n;
    }
}

/* ${prefix}_solve, and *notes (when not NULL) what happened on the way: bit 1 the warm start failed and
   Newton restarted from the coarse grid, bit 2 the basin check kept the coarse grid's lower minimum. */
static int solve_noted(${prefix}_work* w, const double* P, const double* x0, double* x, double* energy_length,
                       int* iterations, int* notes) {
  int i, ok, ok2, more = 0, total;
  double E = NAN, S = NAN, E2, S2, x2[NX];
  if (notes) *notes = 0;
  if (!w || !P || !x || !w->ready) return ${PREFIX}_INVALID_INPUT;
  x[0] = x[1] = NAN;
  if (energy_length) energy_length[0] = energy_length[1] = NAN;
  if (iterations) *iterations = 0;
  for (i = 0; i < NP; ++i)
    if (!isfinite(P[i])) return ${PREFIX}_INVALID_INPUT;
  if (!(P[12] > 0 && P[13] > 0)) return ${PREFIX}_INVALID_INPUT;
  if (x0 && !(isfinite(x0[0]) && isfinite(x0[1]))) return ${PREFIX}_INVALID_INPUT;
  w->arg[0] = P;
  w->res[0] = w->family;
  ${prefix}_family(w->arg, w->res, w->iw, w->w, 0);
  if (x0) {
    x[0] = x0[0];
    x[1] = x0[1];
  } else {
    coarse_start(w, x);
  }
  ok = newton(w, x, &E, &S, &total);
  if (!ok && w->restart && x0) { /* warm start failed: restart from the coarse grid */
    if (notes) *notes |= 1;
    coarse_start(w, x);
    ok = newton(w, x, &E, &S, &more);
    total += more;
  }
  if (ok && w->basin_check && x0) { /* also from the coarse grid; the lower minimum kept */
    coarse_start(w, x2);
    ok2 = newton(w, x2, &E2, &S2, &more);
    total += more;
    if (ok2 && E2 < E - 1e-9 * fabs(E)) {
      if (notes) *notes |= 2;
      x[0] = x2[0];
      x[1] = x2[1];
      E = E2;
      S = S2;
    }
  }
  x[0] = wrap(x[0]);
  x[1] = wrap(x[1]);
  if (energy_length) {
    energy_length[0] = E;
    energy_length[1] = S;
  }
  if (iterations) *iterations = total;
  return ok ? ${PREFIX}_OK : ${PREFIX}_NOT_CONVERGED;
}

int ${prefix}_solve(${prefix}_work* w, const double* P, const double* x0, double* x, double* energy_length,
                    int* iterations) {
  return solve_noted(w, P, x0, x, energy_length, iterations, 0);
}

long ${prefix}_trajectory(${prefix}_work* w, const double* P, long n, double* X, double* energy_length,
                          int* iterations, int* status) {
  long k, failures = 0;
  int s;
  const double* previous = 0;
  for (k = 0; k < n; ++k) {
    s = ${prefix}_solve(w, P + k * NP, previous, X + k * NX, energy_length ? energy_length + 2 * k : 0,
                        iterations ? iterations + k : 0);
    if (status) status[k] = s;
    if (s != ${PREFIX}_OK) failures += 1;
    previous = (w->warm_start && s == ${PREFIX}_OK) ? X + k * NX : 0;
  }
  return failures;
}
