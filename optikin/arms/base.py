"""The interface every arm model offers: CasADi Functions of the configuration ``q``.

An arm subclasses :class:`ArmModel` and writes its kinematics once, as CasADi
``SX`` expressions, in :meth:`ArmModel.section_frames` (the pose of the end of
every section in the base frame) and :meth:`ArmModel.backbone_points`. From
those the base class builds, once and lazily, the Functions that solvers,
controllers and baselines call (DESIGN.md: one model, many uses):

========================  =====================================================
``fk_dq``                 q -> tip pose as a unit dual quaternion (8)
``fk_position``           q -> tip position (3)
``fk_transform``          q -> tip pose as a 4x4 homogeneous transform
``section_dq``            q -> end pose of every section, 8 x m
``jac_position``          q -> d p_tip / d q, 3 x n (automatic differentiation)
``jac_dq``                q -> d Q_tip / d q, 8 x n
``backbone``              q -> points along the backbone, 3 x K
========================  =====================================================

:meth:`ArmModel.evaluate` runs any of them over a batch of configurations with
``Function.map``; :meth:`ArmModel.validate` rejects NaNs, wrong shapes and
configurations outside the bounds, naming the sample and the variable.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from functools import cached_property

import casadi as ca
import numpy as np

from optikin.algebra import dq_from_rotation_translation, dq_translation, transform_from_dq
from optikin.batch import batch_evaluate
from optikin.errors import InputDataError

FUNCTION_NAMES = ("fk_dq", "fk_position", "fk_transform", "section_dq", "jac_position", "jac_dq", "backbone")


class ArmModel(ABC):
    """A continuum arm whose kinematics are CasADi expressions of ``q``.

    Parameters
    ----------
    name:
        Short identifier used in problem files and reports.
    config_names:
        One name per configuration variable, e.g. ``("S1", "theta1", "phi1", ...)``.
    lower, upper:
        Bounds of each configuration variable (SI units).
    backbone_points_per_section:
        Resolution of :attr:`backbone`.
    periodic:
        One flag per variable: True for angles the kinematics are 2 pi-periodic in
        (solvers and controllers wrap them instead of clipping at the bounds).
    """

    def __init__(
        self,
        name: str,
        config_names: tuple[str, ...],
        lower: np.ndarray,
        upper: np.ndarray,
        backbone_points_per_section: int = 20,
        periodic: tuple[bool, ...] | None = None,
    ):
        self.name = name
        self.config_names = tuple(config_names)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        if self.lower.shape != (self.n_config,) or self.upper.shape != (self.n_config,):
            raise ValueError(f"{name}: bounds must have shape ({self.n_config},)")
        if np.any(self.lower > self.upper):
            bad = [n for n, lo, hi in zip(self.config_names, self.lower, self.upper) if lo > hi]
            raise ValueError(f"{name}: lower bound above upper bound for {', '.join(bad)}")
        self.backbone_points_per_section = int(backbone_points_per_section)
        self.periodic = np.zeros(self.n_config, dtype=bool) if periodic is None else np.asarray(periodic, dtype=bool)
        if self.periodic.shape != (self.n_config,):
            raise ValueError(f"{name}: periodic must have one flag per configuration variable")

    @property
    def n_config(self) -> int:
        return len(self.config_names)

    @property
    @abstractmethod
    def n_sections(self) -> int:
        """Number of sections whose end poses :attr:`section_dq` reports."""

    @abstractmethod
    def section_frames(self, q: ca.SX) -> list[tuple[ca.SX, ca.SX]]:
        """``(quaternion 4x1, position 3x1)`` of the end of every section, in the base frame."""

    @abstractmethod
    def backbone_points(self, q: ca.SX, points_per_section: int) -> ca.SX:
        """Points along the backbone from base to tip, ``3 x K`` (base point included)."""

    # ------------------------------------------------------------------ Functions
    @cached_property
    def _q(self) -> ca.SX:
        return ca.SX.sym("q", self.n_config)

    @cached_property
    def _section_dq_expr(self) -> list[ca.SX]:
        return [dq_from_rotation_translation(quat, p) for quat, p in self.section_frames(self._q)]

    def _function(self, name: str, out: ca.SX, out_name: str) -> ca.Function:
        return ca.Function(f"{self.name}_{name}", [self._q], [out], ["q"], [out_name], {"cse": True})

    @cached_property
    def fk_dq(self) -> ca.Function:
        return self._function("fk_dq", self._section_dq_expr[-1], "dq")

    @cached_property
    def fk_position(self) -> ca.Function:
        return self._function("fk_position", dq_translation(self._section_dq_expr[-1]), "p")

    @cached_property
    def fk_transform(self) -> ca.Function:
        return self._function("fk_transform", transform_from_dq(self._section_dq_expr[-1]), "T")

    @cached_property
    def section_dq(self) -> ca.Function:
        return self._function("section_dq", ca.horzcat(*self._section_dq_expr), "dq")

    @cached_property
    def jac_position(self) -> ca.Function:
        p = dq_translation(self._section_dq_expr[-1])
        return self._function("jac_position", ca.jacobian(p, self._q), "J")

    @cached_property
    def jac_dq(self) -> ca.Function:
        return self._function("jac_dq", ca.jacobian(self._section_dq_expr[-1], self._q), "J")

    @cached_property
    def backbone(self) -> ca.Function:
        pts = self.backbone_points(self._q, self.backbone_points_per_section)
        return self._function("backbone", pts, "points")

    # ------------------------------------------------------------------ numeric helpers
    extra_function_names: tuple[str, ...] = ()
    """Names of the arm's own cached Functions beyond :data:`FUNCTION_NAMES`."""

    def function(self, name: str) -> ca.Function:
        """The Function called ``name``: one of :data:`FUNCTION_NAMES` or :attr:`extra_function_names`."""
        known = FUNCTION_NAMES + self.extra_function_names
        if name not in known:
            raise KeyError(f"{self.name} has no function {name!r}; known: {', '.join(known)}")
        return getattr(self, name)

    def evaluate(self, name: str, configurations: np.ndarray) -> np.ndarray:
        """Evaluate Function ``name`` on a batch ``(N, n_config)``; returns ``(N, *out_shape)``.

        One zero-copy call into CasADi for the whole batch (:func:`optikin.batch.batch_evaluate`).
        """
        Q = np.asarray(configurations, dtype=float)
        single = Q.ndim == 1
        out = batch_evaluate(self.function(name), np.atleast_2d(Q))
        if out.shape[2] == 1:
            out = out[..., 0]
        return out[0] if single else out

    def validate(self, configurations: np.ndarray, source: str = "configurations", check_bounds: bool = True,
                 tolerance: float = 1e-12) -> np.ndarray:
        """Return ``configurations`` as a float array ``(N, n_config)`` or raise naming the bad sample.

        Rejects a wrong shape, NaN or infinite entries and (unless ``check_bounds`` is false)
        values outside ``[lower - tolerance, upper + tolerance]``.
        """
        Q = np.asarray(configurations, dtype=float)
        if Q.ndim == 1:
            Q = Q[None, :]
        if Q.ndim != 2 or Q.shape[1] != self.n_config:
            raise InputDataError(
                f"expected shape (N, {self.n_config}) for {self.name} ({', '.join(self.config_names)}), "
                f"got {np.shape(configurations)}",
                source=source,
            )
        bad = ~np.isfinite(Q)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise InputDataError(f"{Q[i, j]} is not a finite number", source=source, sample=int(i),
                                 field=self.config_names[j])
        if check_bounds:
            below = Q < self.lower - tolerance
            above = Q > self.upper + tolerance
            if below.any() or above.any():
                i, j = np.argwhere(below | above)[0]
                raise InputDataError(
                    f"{Q[i, j]:.6g} outside the bounds [{self.lower[j]:.6g}, {self.upper[j]:.6g}]",
                    source=source, sample=int(i), field=self.config_names[j],
                )
        return Q

    def sample_configurations(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` configurations drawn uniformly inside the bounds."""
        return rng.uniform(self.lower, self.upper, size=(n, self.n_config))

    def describe(self) -> dict:
        """Geometry and bounds, for reports and result files."""
        return {
            "name": self.name,
            "config_names": list(self.config_names),
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "periodic": self.periodic.tolist(),
        }

    def transform_of(self, q: np.ndarray) -> np.ndarray:
        """Numeric 4x4 tip transform of one configuration."""
        return np.asarray(self.fk_transform(np.asarray(q, dtype=float)))


def as_transform(dq: np.ndarray) -> np.ndarray:
    """4x4 transforms of numeric dual quaternions ``(..., 8)``."""
    return transform_from_dq(np.asarray(dq, dtype=float))
