"""Closed-loop tracking of a tip reference: the per-step QP controller, its solvers and the simulator (issue 6).

==================  ==========================================================
``task``            the tracked task (tip pose as dual quaternion, or position):
                    Jacobian, error, QP data per step, from the arm's Functions
``fast``            CasADi Functions called in place through ``Function.buffer``
``limits``          configuration + rate limits -> bounds on the rates of one step
``base``            what every controller offers (``command``, ``status``)
``qp``              the constrained QP controller with failure fallbacks
``qp_backends``     OSQP (updated in place), qpsolvers, cvxpy (Parameters / rebuilt)
``reference``       references made by FK of minimum-jerk configuration paths
``simulate``        the closed loop: plant mismatch, disturbance, noise; metrics
``figures``         reference vs actual, errors, limits, V(e), step times
==================  ==========================================================

The classical controllers it is compared with live in :mod:`optikin.baselines`
(``mrac``: seed 000 eqs. 32-35; ``pseudo_inverse``: pseudo-inverse and damped
least squares).
"""
