"""Calibration of continuum arms from recordings: geometry by robust nonlinear least squares over all postures.

* :mod:`optikin.calibration.model`: marker positions of a constant-curvature arm as CasADi
  functions of per-posture bending vectors and shared parameters (section lengths, base pose,
  marker offsets, optionally a linear map from actuator readings);
* :mod:`optikin.calibration.solver`: Levenberg-Marquardt on the Schur complement of the shared
  parameters, robust losses, covariance from the Jacobian at the solution;
* :mod:`optikin.calibration.calibrate`: the start, the robust fit, rejected postures with their
  reasons (label swaps recognised), the refit, the least-squares errors, the held-out error over every
  posture (the outlier rule inside each training fold);
* :mod:`optikin.calibration.identifiability`: what the postures determine (singular values, weak
  combinations, correlations, standard deviations, bounds) and the verdict ``ok`` or ``not_identifiable``;
* :mod:`optikin.calibration.export`: the calibrated ``arm:`` section and the recording re-expressed
  for the ``ik`` and ``ph_shape`` kinds;
* :mod:`optikin.calibration.synthetic`, :mod:`optikin.calibration.cosserat_source`: sources
  ``synthetic`` and ``cosserat`` of data family ``recordings``.

The problem kind is ``calibrate`` (:mod:`optikin.problems.calibrate`).
"""
