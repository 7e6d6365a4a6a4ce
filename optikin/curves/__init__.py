"""Curves for continuum-robot backbones: spatial PH quintics, their energies and minimum-energy choice."""

from optikin.curves.ph_quintic import (
    HermiteFamily,
    PHQuintic,
    hermite_family,
    ph_quintic_hermite,
    preimage,
    validate_hermite_data,
)

__all__ = ["HermiteFamily", "PHQuintic", "hermite_family", "ph_quintic_hermite", "preimage", "validate_hermite_data"]
