/* ${stem}.h: minimum-energy PH quintic backbones of optikin problem ${problem}, exported by `optikin export`.

   Singh et al. 2018, section II.A: the PH quintic Hermite interpolants of the end poses
   (p0, t0) -> (p1, t1) with given end speeds s0, s1 form a two-parameter family (free angles
   phi0, phi2); the member of least energy int kappa^2 ds${twist_note} (${nodes} Gauss-Legendre nodes)
   is the backbone. Minimised by modified Newton (Hessian eigenvalues floored, Armijo backtracking;
   optikin.curves.newton.modified_newton) on the CasADi-generated energy, gradient and Hessian,
   as the ph_newton fast path of optikin.solvers.ph_backends does. The data-only part of the
   family (its roots and pole) is computed once per sample; a full step that quadratic
   convergence predicts to meet the tolerance is checked on E and the gradient alone
   (optikin.curves.newton.converging_step), the Hessian there taken as positive definite.

   Sizes (compile-time constants):
     ${PREFIX}_NX  free parameters x = (phi0, phi2) [rad], returned wrapped into [-pi, pi)
     ${PREFIX}_NP  entries of one sample's parameter vector P (${n_p}), in this order:
                   p0 (3) base point [m], t0 (3) unit base tangent, p1 (3) tip point [m],
                   t1 (3) unit tip tangent, s0, s1 end speeds |r'(0)|, |r'(1)| [m] (> 0),
                   L backbone length [m] (not used with given speeds)

   One sample (${prefix}_solve): Newton from x0, or, with x0 NULL, from the best point of the
   ${coarse_grid} x ${coarse_grid} angle grid. When a warm start fails and work->restart is set, Newton
   restarts from the grid; with work->basin_check, a converged warm start is also compared with
   Newton from the grid and the lower minimum kept (energies differing by more than 1e-9 |E|).
   A trajectory (${prefix}_trajectory) warm-starts each sample from the previous sample's
   solution when that one is OK and work->warm_start is set, as optikin's PH solvers do.

   Memory: every array lives in ${prefix}_work, which the caller allocates (statically, on the
   stack or once at start-up) and prepares with ${prefix}_init. Nothing is allocated by the
   library. A work structure serves one thread at a time. The options in it, set by init to the
   problem's solver preset (${preset}), may be changed between calls:
     tolerance       converged when max|grad E| <= tolerance (1 + |E|) with a positive definite Hessian
     max_iterations  Newton steps per run of Newton
     warm_start      1: a trajectory starts each sample from the previous OK solution
     restart         1: a failed warm start restarts from the coarse grid
     basin_check     1: a converged warm start is checked against the coarse grid's minimum

   Status codes (enum ${prefix}_status):
     ${PREFIX}_OK             converged; x, E, S of the minimum
     ${PREFIX}_NOT_CONVERGED  Newton did not converge (nor from the grid, with restart); x, E, S
                              of the last iterate. The Python fast path falls back to IPOPT here.
     ${PREFIX}_INVALID_INPUT  a null pointer, a non-finite entry of P or x0, or an end speed <= 0;
                              x, E, S are NaN
*/
#ifndef ${PREFIX}_H
#define ${PREFIX}_H

#ifdef __cplusplus
extern "C" {
#endif

#define ${PREFIX}_NX 2
#define ${PREFIX}_NP ${n_p}

enum ${prefix}_status { ${PREFIX}_OK = 0, ${PREFIX}_NOT_CONVERGED = 2, ${PREFIX}_INVALID_INPUT = 3 };

/* Work arrays (sizes fixed at export; treat them as private) and options (see above). */
typedef struct {
  const double* arg[${sz_arg}];
  double* res[${sz_res}];
  long long iw[${sz_iw}];
  double w[${sz_w}];
  double family[${n_family}]; /* the sample's Hermite family (optikin.export.ph_shape.FAMILY_FIELDS) */
  double grid[${coarse_grid} * ${coarse_grid}];
  double buffers[2][7];
  double* now;
  double* trial;
  double xt[${PREFIX}_NX];
  double tolerance;
  int max_iterations;
  int warm_start;
  int restart;
  int basin_check;
  int ready;
} ${prefix}_work;

/* Prepare the work structure and set the options to the preset's (no allocation). Call once. */
void ${prefix}_init(${prefix}_work* work);

/* One sample: parameters P (NP), start x0 (NX; NULL: the coarse grid's best point). Writes the
   solution into x (NX), its energy E and arc length S [m] into energy_length (2) and the Newton steps
   taken into *iterations (either may be NULL). Returns an enum ${prefix}_status. */
int ${prefix}_solve(${prefix}_work* work, const double* P, const double* x0, double* x, double* energy_length,
                    int* iterations);

/* A trajectory of n samples: row k of the row-major n x NP array P. X (n x NX, row-major) receives
   the solutions, energy_length (n x 2), iterations (n) and status (n) may be NULL. Returns the
   number of samples whose status is not ${PREFIX}_OK. */
long ${prefix}_trajectory(${prefix}_work* work, const double* P, long n, double* X, double* energy_length,
                          int* iterations, int* status);

#ifdef __cplusplus
}
#endif
#endif
