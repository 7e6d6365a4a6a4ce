"""Periodic variables: one way to bring an angle (or any variable of a full-turn range) back into its range."""

from __future__ import annotations

from typing import Literal

import numpy as np


def wrap_periodic(
    x: np.ndarray | float,
    lower: np.ndarray | float = -np.pi,
    upper: np.ndarray | float = np.pi,
    closed: Literal["lower", "upper"] = "lower",
) -> np.ndarray:
    """``x`` wrapped by whole periods ``upper - lower`` into ``[lower, upper)`` (or ``(lower, upper]``).

    Parameters
    ----------
    x:
        Values to wrap (any shape; NaN stays NaN).
    lower, upper:
        The range, broadcast against ``x``; the period is ``upper - lower`` (``2 pi`` by default).
    closed:
        Which end belongs to the range: ``"lower"`` gives ``[lower, upper)``, ``"upper"`` gives
        ``(lower, upper]``.

    Returns
    -------
    np.ndarray
        A new array (a numpy scalar for a scalar ``x``): ``lower + mod(x - lower, period)``, or
        ``upper - mod(upper - x, period)`` with ``closed="upper"``.
    """
    period = np.subtract(upper, lower)
    if closed == "upper":
        return np.subtract(upper, np.mod(np.subtract(upper, x), period))
    return np.add(lower, np.mod(np.subtract(x, lower), period))
