"""Closed-loop tracking of a tip reference: the per-step QP controller and the simulator.

======================  ======================================================
``task``                the tracked task (tip pose as dual quaternion, or position):
                        Jacobian, error, QP data per step, from the arm's Functions
``limits``              configuration + rate limits -> bounds on the rates of one step
``base``                what every controller offers (``command``, ``status``)
``qp``                  the constrained QP controller with failure fallbacks
``obstacles``           obstacles around the whole backbone: distances, barrier rows
``mpc``                 model predictive tracking: one sparse QP per step over a horizon
``mpc_nlp``             the MPC's nonlinear reference, solved by IPOPT
``self_collision``      two arms in one frame: tube distances and their barrier rows
``two_arm``             one QP per step over two arms' rates (a rope they hold, or tips)
``two_arm_obstacles``   obstacles kept off both arms' tubes and the rope they hold
``reference``           references made by FK of minimum-jerk configuration paths
``rod_plant``           a pneumatic Cosserat rod as the tracked plant
``simulate``            the closed loop: plant mismatch, disturbance, noise; metrics
======================  ======================================================

The QP's solvers are the ``qp`` backends of :mod:`optikin.solvers.qp`; the
classical controllers it is compared with live in :mod:`optikin.baselines`
(``mrac``: Seleem et al. 2020, eqs. 32-35; ``pseudo_inverse``: pseudo-inverse and
damped least squares); the figures of a run in :mod:`optikin.problems.tracking.figures`.
"""
