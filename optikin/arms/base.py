"""The interface every arm model offers: CasADi Functions of the configuration ``q``.

An arm subclasses :class:`ArmModel` and writes its kinematics once, as CasADi
``SX`` expressions, in :meth:`ArmModel.section_frames` (the pose of the end of
every section in the base frame) and :meth:`ArmModel.backbone_points`. From
those the base class builds, once and lazily, the Functions that solvers,
controllers and baselines call (one model, many uses):

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

Checked inputs (``docs/conventions.md``): a numeric call of a Function (``arm.fk_dq(q)``)
refuses ``q`` that is not numbers (:class:`TypeError`), not one configuration, not finite,
more than a range (:data:`optikin.checks.NEAR_SPANS`) outside the arm's bounds or with a
length not positive (:class:`ValueError`), naming ``q`` and the variable;
:meth:`ArmModel.evaluate` and the numeric paths of :meth:`ArmModel.section_frames` refuse
non-finite and implausible configurations (:data:`optikin.checks.PLAUSIBLE_SPANS`). Symbolic
calls, ``map``, buffers, code generation and :attr:`ArmFunction.unchecked` are the raw
CasADi Function: unchecked, for the inner loops of solvers.
"""

from __future__ import annotations

import inspect
from abc import ABC, abstractmethod
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from optikin.algebra import dq_from_rotation_translation, dq_translation, transform_from_dq
from optikin.algebra.backend import Array, is_casadi
from optikin.batch import batch_evaluate
from optikin.checks import ParameterError, check_configuration, check_numbers, configuration_limits
from optikin.errors import InputDataError
from optikin.fk_soa import soa_evaluate

FUNCTION_NAMES = ("fk_dq", "fk_position", "fk_transform", "section_dq", "jac_position", "jac_dq", "backbone")
"""The Functions every arm offers (table in the module docstring)."""

CALLING = """

``f(q)``, with one configuration ``q`` (numpy ``(n_config,)``, a list, or a CasADi column
``n_config x 1``), returns a ``casadi.DM`` (``numpy.asarray(f(q))`` or ``f(q).full()`` convert it); a
symbolic ``q`` (``SX``/``MX``) gives the expression. A numeric ``q`` is checked: numbers
(else :class:`TypeError`), one configuration, finite, within one range of the arm's bounds with
lengths positive, periodic angles excepted (else :class:`ValueError` naming the variable). It
is a :class:`casadi.Function`: ``map``, code generation, buffers and ``f.unchecked`` (the raw
Function) work as usual and are not checked, for speed. For a batch ``Q (N, n_config)`` use
``arm.evaluate(name, Q)``, one call for all rows.
"""
"""How to call an arm Function; ends the docstring of every :class:`ArmFunction`."""


class ArmFunction(ca.Function):
    """A CasADi Function of one configuration that checks a numeric configuration before calling CasADi.

    It is a :class:`casadi.Function` (symbolic calls, ``map``, code generation and buffers work
    as usual and are not checked). A numeric call ``f(q)`` (numpy, list, tuple, number or
    ``casadi.DM``) checks ``q`` first (:func:`optikin.checks.check_configuration` with ``within``):
    a string, ``None`` or a complex value is a :class:`TypeError` naming ``q`` (instead of
    CasADi's "Wrong number or type of arguments"); a batch ``(N, n_config)`` or ``(n_config, N)``,
    a wrong length, a non-finite value, a value more than a range outside the bounds or a length
    that is not positive is a :class:`ValueError` naming ``q`` and the variable (batches go through
    :meth:`ArmModel.evaluate`).
    :attr:`unchecked` is the raw Function, for inner loops.

    ``help(arm.fk_dq)`` shows ``doc`` (what the Function computes: shapes, units, frame), not the
    help of :class:`casadi.Function`.

    Parameters
    ----------
    function : casadi.Function
        The Function, one input ``q`` (``n_config x 1``).
    arm : ArmModel
        The arm whose configuration ``q`` is (names and bounds, for the checks and messages).
    short_name : str
        The Function's name on the arm (``fk_dq``), for the message.
    doc : str
        The docstring of this Function (the arm's property that builds it).
    within : {"near", "finite"}
        How far from the bounds a numeric ``q`` may lie (:func:`optikin.checks.configuration_limits`):
        ``"near"`` for the kinematics; ``"finite"`` for a Function that measures feasibility (the CBHA's
        leg lengths), which solvers evaluate at infeasible configurations too.
    """

    def __init__(
        self, function: ca.Function, arm: ArmModel, short_name: str, doc: str = "", within: str = "near"
    ) -> None:
        super().__init__(function)
        self._raw, self._arm, self._within = function, arm, within
        self.arm_name, self.short_name = arm.name, short_name
        self._low, self._high = configuration_limits(arm, within)
        self.__doc__ = inspect.cleandoc(doc) + CALLING if doc else CALLING.lstrip()

    @property
    def unchecked(self) -> ca.Function:
        """The raw :class:`casadi.Function`: the same computation without the input checks of a numeric call.

        For inner loops that have checked their configurations once; NaN in gives NaN out, and a
        configuration outside the bounds is evaluated as given.
        """
        return self._raw

    def _checked(self, q: Any) -> Any:
        """``q`` as a checked ``(n_config,)`` float array; a symbolic ``q`` unchanged."""
        if isinstance(q, (ca.SX, ca.MX)):
            return q
        values = check_numbers(np.asarray(q) if isinstance(q, ca.DM) else q, "q")
        n = self.size1_in(0)
        shape = values.shape
        if shape in ((n,), (n, 1), (1, n)) or (n == 1 and values.ndim == 0):
            flat = values.reshape(n)
            if (flat >= self._low).all() and (flat <= self._high).all():
                return flat
            return check_configuration(self._arm, flat, within=self._within)
        evaluate = f"arm.evaluate({self.short_name!r}, Q)"
        if values.ndim == 2 and shape[1] == n:
            raise ValueError(
                f"q: takes one configuration of shape ({n},), got shape {shape}; for a batch (N, {n}) use {evaluate}"
            )
        if values.ndim == 2 and shape[0] == n:
            raise ValueError(
                f"q: takes one configuration of shape ({n},), got shape {shape}, a batch as columns; batches are "
                f"rows (N, {n}): use {evaluate} with Q = q.T"
            )
        raise ValueError(
            f"q: takes one configuration of shape ({n},), got shape {shape} ({', '.join(self._arm.config_names)})"
        )

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        try:
            if len(args) == 1 and not kwargs:
                args = (self._checked(args[0]),)
            elif not args and set(kwargs) == {"q"}:
                kwargs = {"q": self._checked(kwargs["q"])}
        except TypeError as exc:
            raise TypeError(f"{self.arm_name}.{self.short_name}: {exc}") from None
        except ValueError as exc:
            raise ValueError(f"{self.arm_name}.{self.short_name}: {exc}") from None
        return super().__call__(*args, **kwargs)


class ArmModel(ABC):
    """A continuum arm whose kinematics are CasADi expressions of ``q``.

    Parameters
    ----------
    name : str
        Short identifier used in problem files, Function names and reports.
    config_names : tuple of str
        One name per configuration variable, e.g. ``("S1", "theta1", "phi1", ...)``.
    lower, upper : numpy.ndarray
        Bounds of each configuration variable, ``(n_config,)``, SI units (m, rad).
    backbone_points_per_section : int
        Resolution of :attr:`backbone`.
    periodic : tuple of bool, optional
        One flag per variable: True for angles the kinematics are 2 pi-periodic in
        (solvers and controllers wrap them instead of clipping at the bounds).
        Default: none.
    positive : tuple of bool, optional
        One flag per variable: True for lengths that must stay above 0 whatever the slack of a
        check (:func:`optikin.checks.configuration_limits`). Default: none.

    Raises
    ------
    ValueError
        When the bounds or the flags do not have one entry per variable, a bound is not a
        finite number, or a lower bound lies above its upper bound; an
        :class:`optikin.checks.ParameterError` for ``backbone_points_per_section`` not a
        positive integer, or a ``name`` that is not an identifier.
    """

    def __init__(
        self,
        name: str,
        config_names: tuple[str, ...],
        lower: np.ndarray,
        upper: np.ndarray,
        backbone_points_per_section: int = 20,
        periodic: tuple[bool, ...] | None = None,
        positive: tuple[bool, ...] | None = None,
    ) -> None:
        if not isinstance(name, str) or not name.isidentifier():
            raise ParameterError(
                "name", f"{name!r} is not an identifier (letters, digits, underscores): it names Functions"
            )
        self.name = name
        self.config_names = tuple(config_names)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        if self.lower.shape != (self.n_config,) or self.upper.shape != (self.n_config,):
            raise ValueError(f"{name}: bounds must have shape ({self.n_config},)")
        if np.any(self.lower > self.upper):
            bad = [n for n, lo, hi in zip(self.config_names, self.lower, self.upper) if lo > hi]
            raise ValueError(f"{name}: lower bound above upper bound for {', '.join(bad)}")
        for bound, values in (("lower", self.lower), ("upper", self.upper)):
            if not np.all(np.isfinite(values)):
                j = int(np.argmax(~np.isfinite(values)))
                raise ValueError(f"{name}: {bound} bound of {self.config_names[j]} is not a finite number")
        points = backbone_points_per_section
        if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 1:
            raise ParameterError("backbone_points_per_section", f"must be a positive integer, got {points!r}")
        self.backbone_points_per_section = int(points)
        self.periodic = np.zeros(self.n_config, dtype=bool) if periodic is None else np.asarray(periodic, dtype=bool)
        if self.periodic.shape != (self.n_config,):
            raise ValueError(f"{name}: periodic must have one flag per configuration variable")
        self.positive = np.zeros(self.n_config, dtype=bool) if positive is None else np.asarray(positive, dtype=bool)
        if self.positive.shape != (self.n_config,):
            raise ValueError(f"{name}: positive must have one flag per configuration variable")

    @property
    def n_config(self) -> int:
        """Number of configuration variables ``n``."""
        return len(self.config_names)

    @property
    @abstractmethod
    def n_sections(self) -> int:
        """Number of sections ``m`` whose end poses :attr:`section_dq` reports."""

    @abstractmethod
    def section_frames(self, q: Array) -> list[tuple[Array, Array]]:
        """End pose of every section in the base frame, base section first.

        Parameters
        ----------
        q : Array
            Configurations: a CasADi column ``n_config x 1`` (every arm) or a numpy batch
            ``(..., n_config)`` (arms whose kinematics are written on :mod:`optikin.algebra.backend`).

        Returns
        -------
        list of (Array, Array)
            ``m`` pairs ``(quaternion, position [m])``: CasADi ``4 x 1`` and ``3 x 1``, or
            numpy ``(..., 4)`` and ``(..., 3)``.
        """

    def frame_at(self, q: Array, section: int, fraction: float = 1.0) -> tuple[Array, Array]:
        """Pose of the backbone frame at a fraction of one section's arc length, in the base frame.

        Parameters
        ----------
        q : Array
            Configuration, as for :meth:`section_frames`.
        section : int
            Section index from 0 (base section).
        fraction : float
            Fraction of the section's arc length in ``(0, 1]``; arms whose sections are not
            continua (this base implementation) offer the section ends only, ``fraction = 1``.

        Returns
        -------
        (Array, Array)
            ``(quaternion, position [m])``.

        Raises
        ------
        ValueError
            ``section`` out of range, or a fraction the arm does not offer.
        """
        if not 0 <= section < self.n_sections:
            raise ValueError(f"section {section + 1} out of range: {self.name} has {self.n_sections} sections")
        if fraction != 1.0:
            raise ValueError(f"{self.name} offers points at section ends only (fraction 1), not {fraction:g}")
        return self.section_frames(q)[section]

    @abstractmethod
    def backbone_points(self, q: ca.SX, points_per_section: int) -> ca.SX:
        """Points along the backbone from base to tip, in the base frame.

        Parameters
        ----------
        q : casadi.SX
            Configuration, ``n_config x 1``.
        points_per_section : int
            Points per section after the base point.

        Returns
        -------
        casadi.SX
            ``3 x K`` [m], ``K = 1 + m points_per_section``, the base point first.
        """

    # ------------------------------------------------------------------ Functions
    @cached_property
    def _q(self) -> ca.SX:
        return ca.SX.sym("q", self.n_config)

    @cached_property
    def _section_dq_expr(self) -> list[ca.SX]:
        return [dq_from_rotation_translation(quat, p, check=False) for quat, p in self.section_frames(self._q)]

    def _function(self, name: str, out: ca.SX, out_name: str, within: str = "near") -> ca.Function:
        f = ca.Function(f"{self.name}_{name}", [self._q], [out], ["q"], [out_name], {"cse": True})
        return ArmFunction(f, self, name, getattr(type(self), name).__doc__ or "", within)

    def checked_numeric(self, q: Array, name: str = "q") -> Array:
        """A numeric ``q`` checked as configurations ``(..., n_config)``, finite and plausible; CasADi unchanged.

        The check of the numeric paths of :meth:`section_frames` and the other kinematic methods
        (:func:`optikin.checks.check_configuration` with ``within="plausible"``).

        Parameters
        ----------
        q : Array
            Configurations: numpy (any batch shape), a list, or a CasADi matrix (not checked).
        name : str
            The argument's name, for the message.

        Returns
        -------
        Array
            ``q`` as a float array, or the CasADi matrix itself.

        Raises
        ------
        TypeError
            For values that are not numbers.
        ValueError
            For a wrong shape, a non-finite value or one far outside the bounds.
        """
        if is_casadi(q):
            return q
        return check_configuration(self, q, name, within="plausible", batch=True)

    @cached_property
    def fk_dq(self) -> ca.Function:
        """Tip pose as a unit dual quaternion (seed 000 eqs. 9-10): ``fk_dq(q)`` is an ``8 x 1`` DM.

        ``q`` is one configuration ``(n_config,)`` in :attr:`config_names` order, SI units (m, rad).
        The result is ``(Q_r, Q_d)``: the tip frame's rotation ``Q_r = (w, x, y, z)`` and
        ``Q_d = 0.5 (0, p) Q_r`` with the tip position ``p`` [m], in the arm's base frame (origin at
        the base centre, z along the unbent backbone; the tip frame's z axis is the backbone tangent).
        """
        return self._function("fk_dq", self._section_dq_expr[-1], "dq")

    @cached_property
    def fk_position(self) -> ca.Function:
        """Tip position: ``fk_position(q)`` is a ``3 x 1`` DM [m] in the arm's base frame.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad).
        """
        return self._function("fk_position", dq_translation(self._section_dq_expr[-1]), "p")

    @cached_property
    def fk_transform(self) -> ca.Function:
        """Tip pose as a homogeneous transform: ``fk_transform(q)`` is a ``4 x 4`` DM ``[R, p; 0, 1]``.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad); ``R`` and ``p`` [m] place the tip
        frame in the base frame, the same pose as :attr:`fk_dq`.
        """
        return self._function("fk_transform", transform_from_dq(self._section_dq_expr[-1]), "T")

    @cached_property
    def section_dq(self) -> ca.Function:
        """End pose of every section: ``section_dq(q)`` is an ``8 x m`` DM, base section first.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad). Column ``i`` is ``(Q_r, Q_d)`` of the
        end of section ``i + 1`` in the base frame (translation in metres), as :attr:`fk_dq` for the tip.
        """
        return self._function("section_dq", ca.horzcat(*self._section_dq_expr), "dq")

    @cached_property
    def jac_position(self) -> ca.Function:
        """Position Jacobian ``d p_tip / d q`` (seed 000 eqs. 3-4): ``jac_position(q)`` is a ``3 x n_config`` DM.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad). Column ``j`` is the derivative of the
        tip position [m], in the base frame, with respect to variable ``j``, by automatic differentiation.
        """
        p = dq_translation(self._section_dq_expr[-1])
        return self._function("jac_position", ca.jacobian(p, self._q), "J")

    @cached_property
    def jac_dq(self) -> ca.Function:
        """Dual-quaternion Jacobian ``d Q_tip / d q`` (seed 000 eq. 33): ``jac_dq(q)`` is an ``8 x n_config`` DM.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad). Column ``j`` is the derivative of
        :attr:`fk_dq`'s ``(Q_r, Q_d)`` with respect to variable ``j`` (the dual part in metres per the
        variable's unit), by automatic differentiation.
        """
        return self._function("jac_dq", ca.jacobian(self._section_dq_expr[-1], self._q), "J")

    @cached_property
    def backbone(self) -> ca.Function:
        """Points along the backbone: ``backbone(q)`` is a ``3 x K`` DM [m] in the base frame, base point first.

        ``q`` is one configuration ``(n_config,)``, SI units (m, rad); ``K = 1 + m`` :attr:`backbone_points_per_section`
        (:meth:`backbone_points`).
        """
        pts = self.backbone_points(self._q, self.backbone_points_per_section)
        return self._function("backbone", pts, "points")

    # ------------------------------------------------------------------ numeric helpers
    extra_function_names: tuple[str, ...] = ()
    """Names of the arm's own cached Functions beyond :data:`FUNCTION_NAMES`."""

    def function(self, name: str) -> ca.Function:
        """The Function called ``name``.

        Parameters
        ----------
        name : str
            One of :data:`FUNCTION_NAMES` or :attr:`extra_function_names`.

        Returns
        -------
        casadi.Function
            Built on first use and cached; one input ``q`` (``n_config x 1``).

        Raises
        ------
        KeyError
            For an unknown name, listing the known ones.
        """
        known = FUNCTION_NAMES + self.extra_function_names
        if name not in known:
            raise KeyError(f"{self.name} has no function {name!r}; known: {', '.join(known)}")
        return getattr(self, name)

    def evaluate(self, name: str, configurations: np.ndarray, check: bool = True, bounds: bool = False) -> np.ndarray:
        """Evaluate the Function ``name`` on a batch of configurations.

        One zero-copy call into CasADi for the whole batch (:func:`optikin.batch.batch_evaluate`);
        the tip pose of a constant-curvature arm through a vectorised C loop instead
        (:func:`optikin.fk_soa.soa_evaluate`, within 1e-14 of it).
        The type and the shape are always checked. ``check`` refuses NaN, infinite and implausible
        values (more than :data:`optikin.checks.PLAUSIBLE_SPANS` ranges outside the bounds: a unit
        mistake); ``bounds`` refuses any value outside the bounds (periodic angles excepted). With
        ``check=False`` a row with a NaN gives NaN outputs (a failed sample stays failed).

        Parameters
        ----------
        name : str
            A name accepted by :meth:`function`.
        configurations : numpy.ndarray
            ``(N, n_config)``, or one configuration ``(n_config,)``.
        check : bool
            Whether to require finite, plausible configurations (:func:`optikin.checks.check_configuration`).
        bounds : bool
            Whether to require configurations inside the bounds.

        Returns
        -------
        numpy.ndarray
            ``(N, rows)`` for a column output (e.g. ``fk_dq``: ``(N, 8)``), ``(N, rows, cols)``
            otherwise (e.g. ``section_dq``: ``(N, 8, m)``); without the leading ``N`` for one
            configuration.

        Raises
        ------
        TypeError
            For configurations that are not numbers, naming ``configurations``.
        ValueError
            For a wrong shape; with ``check`` or ``bounds``, naming the sample and the variable.
        """
        Q = check_numbers(configurations, "configurations")
        if Q.ndim not in (1, 2) or Q.shape[-1] != self.n_config:
            raise ValueError(
                f"configurations: expected shape (N, {self.n_config}) or ({self.n_config},) for {self.name} "
                f"({', '.join(self.config_names)}), got shape {Q.shape}"
            )
        if check or bounds:
            within = "bounds" if bounds else "plausible"
            check_configuration(self, Q, name="configurations", within=within, batch=True)
        single = Q.ndim == 1
        fast = soa_evaluate(self, name, np.atleast_2d(Q))
        if fast is not None:
            return fast[0] if single else fast
        out = batch_evaluate(self.function(name), np.atleast_2d(Q))
        if out.shape[2] == 1:
            out = out[..., 0]
        return out[0] if single else out

    def validate(
        self,
        configurations: np.ndarray,
        source: str = "configurations",
        check_bounds: bool = True,
        tolerance: float = 1e-12,
    ) -> np.ndarray:
        """Check a batch of configurations; raise naming the bad sample and variable.

        Rejects a wrong shape, NaN or infinite entries and (unless ``check_bounds`` is false)
        values outside ``[lower - tolerance, upper + tolerance]``.

        Parameters
        ----------
        configurations : numpy.ndarray
            ``(N, n_config)`` or one configuration ``(n_config,)``, SI units.
        source : str
            Where the data came from, for the error message.
        check_bounds : bool
            Whether to check the bounds :attr:`lower`, :attr:`upper`.
        tolerance : float
            Slack on the bounds, in the variables' units.

        Returns
        -------
        numpy.ndarray
            The configurations as floats, ``(N, n_config)``.

        Raises
        ------
        optikin.errors.InputDataError
            Naming ``source``, the sample and the variable.
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
            raise InputDataError(
                f"{Q[i, j]} is not a finite number", source=source, sample=int(i), field=self.config_names[j]
            )
        if check_bounds:
            below = Q < self.lower - tolerance
            above = Q > self.upper + tolerance
            if below.any() or above.any():
                i, j = np.argwhere(below | above)[0]
                raise InputDataError(
                    f"{Q[i, j]:.6g} outside the bounds [{self.lower[j]:.6g}, {self.upper[j]:.6g}]",
                    source=source,
                    sample=int(i),
                    field=self.config_names[j],
                )
        return Q

    def sample_configurations(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Configurations drawn uniformly inside the bounds.

        Parameters
        ----------
        n : int
            Number of configurations.
        rng : numpy.random.Generator
            Source of the draws.

        Returns
        -------
        numpy.ndarray
            ``(n, n_config)``.
        """
        return rng.uniform(self.lower, self.upper, size=(n, self.n_config))

    def describe(self) -> dict[str, Any]:
        """Geometry and bounds, for reports and result files.

        Returns
        -------
        dict
            JSON-serialisable: ``name``, ``config_names``, ``lower``, ``upper``, ``periodic``
            (subclasses add their geometry).
        """
        return {
            "name": self.name,
            "config_names": list(self.config_names),
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "periodic": self.periodic.tolist(),
        }

    def transform_of(self, q: np.ndarray, check: bool = True) -> np.ndarray:
        """Numeric tip transform of one configuration or a batch.

        Parameters
        ----------
        q : numpy.ndarray
            One configuration ``(n_config,)`` or a batch ``(N, n_config)``, SI units.
        check : bool
            Whether to require finite values inside the bounds (:func:`optikin.checks.check_configuration`).

        Returns
        -------
        numpy.ndarray
            ``(4, 4)`` homogeneous transform (``(N, 4, 4)`` for a batch), translation in metres.

        Raises
        ------
        ValueError
            For a wrong shape; with ``check``, a non-finite value or one outside the bounds.
        """
        if check:
            check_configuration(self, q, batch=True)
        return self.evaluate("fk_transform", q, check=False)
