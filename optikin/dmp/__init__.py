"""Dynamic movement primitives per angle, on unit quaternions, on dual quaternions (Seleem et al. 2020, III-C, IV).

I. A. Seleem, H. El-Hussieny, S. F. M. Assal, H. Ishii, "Development and Stability Analysis of an Imitation
Learning-Based Pose Planning Approach for Multi-Section Continuum Robot", IEEE Access, 2020
(doi:10.1109/ACCESS.2020.2997636): the equation numbers in this package are theirs.

* :mod:`~optikin.dmp.spaces` -- the spaces a DMP moves in (gap and advance operations).
* :mod:`~optikin.dmp.canonical`, :mod:`~optikin.dmp.basis` -- phase (eqs. 15, 25, 28) and forcing-term basis (13-14).
* :mod:`~optikin.dmp.smoothing` -- optional low-pass of noisy (sensor) demonstrations before learning.
* :mod:`~optikin.dmp.imitation`, :mod:`~optikin.dmp.regression` -- targets (16, 21-22) and weight fits.
* :mod:`~optikin.dmp.rollout` -- the roll-out as one CasADi Function (11-12, 17-18, 23-28).
* :mod:`~optikin.dmp.model` -- :class:`DMP`: imitate, roll out, generalise.
* :mod:`~optikin.dmp.pose` -- Seleem et al.'s dual-quaternion DMP and the sound variants.
* :class:`~optikin.dmp.spaces.GoalLogQuaternion` -- Koutras & Doulgeri's (CoRL 2020) orientation DMP in the
  logarithm of the rotation to the goal.
* :mod:`~optikin.dmp.tuning` -- gains by minimising the reproduction error (eq. 29).
"""

from optikin.dmp.gains import GAIN_NAMES, Gains, stable_bounds
from optikin.dmp.model import DMP, Rollout
from optikin.dmp.regression import Fit
from optikin.dmp.spaces import Euclidean, GoalLogQuaternion, Product, Space, UnitDualQuaternion, UnitQuaternion

__all__ = [
    "DMP",
    "Euclidean",
    "Fit",
    "GAIN_NAMES",
    "Gains",
    "GoalLogQuaternion",
    "Product",
    "Rollout",
    "Space",
    "UnitDualQuaternion",
    "UnitQuaternion",
    "stable_bounds",
]
