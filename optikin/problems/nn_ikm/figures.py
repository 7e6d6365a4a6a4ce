"""Figures of ``nn_ikm`` from a result's arrays and summary: width searches and tip errors."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from optikin.problems import nn_shared
from optikin.results import Drawer


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``search`` and ``tip_errors`` (:func:`optikin.problems.nn_shared.figures`)."""
    return nn_shared.figures(arrays, summary, "IKM")
