"""Curves for continuum-robot backbones: spatial PH quintics, their energies and minimum-energy choice.

A backbone from its two end poses (Singh et al. 2018, section II.A): the
minimum-energy PH quintic of the end points and tangents, its length estimated
from them (or known), here a quarter circle of radius 0.2 m:

>>> import numpy as np
>>> from optikin.curves import ShapeData, ShapeEnergyModel, arc_length_estimate
>>> p0, t0, p1, t1 = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.2, 0.0, 0.2]), np.array([1.0, 0.0, 0.0])
>>> data = ShapeData.checked(p0, t0, p1, t1, length=arc_length_estimate(p0, t0, p1, t1))
>>> model = ShapeEnergyModel(free_speeds=True)  # end speeds free, arc length held to the length
>>> curve = model.curve(model.solve_newton(data), data)  # a PHQuintic: points, frames, curvature...
>>> round(float(curve.arc_length()), 6)  # pi / 10
0.314159

``EnergySettings`` chooses the energy (twist weight, quadrature nodes);
:meth:`ShapeEnergyModel.solve_nlp` (IPOPT) and :meth:`ShapeEnergyModel.solve_grid`
are the reference and the baseline of :meth:`ShapeEnergyModel.solve_newton`, and
:meth:`ShapeEnergyModel.curves` gives the curves of many solutions as one batch.
"""

from optikin.curves.min_energy import (
    EnergySettings,
    ShapeData,
    ShapeEnergyModel,
    ShapeParameters,
    ShapeSolution,
    arc_length_estimate,
)
from optikin.curves.ph_quintic import (
    HermiteFamily,
    PHQuintic,
    hermite_family,
    ph_quintic_hermite,
    preimage,
    validate_hermite_data,
)

__all__ = [
    "EnergySettings",
    "HermiteFamily",
    "PHQuintic",
    "ShapeData",
    "ShapeEnergyModel",
    "ShapeParameters",
    "ShapeSolution",
    "arc_length_estimate",
    "hermite_family",
    "ph_quintic_hermite",
    "preimage",
    "validate_hermite_data",
]
