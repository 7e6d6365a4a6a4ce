"""Inverse kinematics posed as bounded nonlinear least squares.

:mod:`optikin.ik.formulation` turns an arm and a target kind (tip position, tip
pose, section ends, CBHA legs) into a :class:`~optikin.solvers.nonlinear.LeastSquaresProblem`;
:mod:`optikin.ik.cbha` holds the CBHA's elongation distributions and leg checks;
:mod:`optikin.ik.platform` solves the CBHA's 3UPS-1UP platforms from leg lengths.
"""
