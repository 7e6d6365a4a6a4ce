"""Validators of the numeric inputs of the Python API, in the style of pytransform3d's ``check_*``.

Each ``check_*`` function returns its input as a float array when it is usable and
raises :class:`ValueError` naming the argument (and the entry) and what is wrong
otherwise:

* :func:`check_quaternion`: shape ``(..., 4)``, finite, unit norm within a tolerance;
* :func:`check_dual_quaternion`: shape ``(..., 8)``, finite, a unit real part and a dual
  part orthogonal to it (``Q_r . Q_d = 0``, Seleem et al. 2020, eqs. 9-10);
* :func:`check_configuration`: one configuration ``(n,)`` (or a batch ``(N, n)``) of an arm,
  finite, inside the arm's bounds (periodic angles excepted);
* :func:`check_parameter`: a model parameter (scalar or vector), finite, optionally positive;
  raises :class:`ParameterError`, which carries the parameter's field name.

They are numpy-only and meant for the public entry points; inner loops call the unchecked
functions (or pass ``check=False`` where a function offers it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from optikin.arms.base import ArmModel

UNIT_TOLERANCE = 1e-6
"""Default largest accepted ``| |q| - 1 |`` (and ``|Q_r . Q_d|`` of a dual quaternion)."""
BOUND_TOLERANCE = 1e-9
"""Default slack on an arm's bounds, relative to each variable's range (absolute for a fixed variable)."""


class ParameterError(ValueError):
    """An unusable model parameter: ``field`` its dotted name (``section_lengths.0``), ``message`` what is wrong."""

    def __init__(self, field: str, message: str) -> None:
        self.field, self.message = field, message
        super().__init__(f"{field}: {message}")


def _as_float(value: object, name: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected numbers, got {value!r}") from None


def _where(name: str, shape: tuple[int, ...], flat_index: int) -> str:
    """``name[i, j]`` for entry ``flat_index`` of a batch of shape ``shape`` (``name`` alone when unbatched)."""
    if not shape:
        return name
    index = np.unravel_index(flat_index, shape)
    return f"{name}[{', '.join(str(int(i)) for i in index)}]"


def _check_rows(values: np.ndarray, name: str, width: int, what: str) -> np.ndarray:
    """``values`` of shape ``(..., width)`` with finite entries, as rows ``(M, width)``."""
    if values.ndim == 0 or values.shape[-1] != width:
        raise ValueError(f"{name}: expected {what} of shape ({width},) or (..., {width}), got shape {values.shape}")
    rows = values.reshape(-1, width)
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{_where(name, values.shape[:-1], i)}: {rows[i].tolist()} has a non-finite component")
    return rows


def check_quaternion(q: object, unit: bool = True, name: str = "q", tolerance: float = UNIT_TOLERANCE) -> np.ndarray:
    """Check Hamilton quaternions ``(w, x, y, z)``.

    Parameters
    ----------
    q : array_like
        One quaternion ``(4,)`` or a batch ``(..., 4)``.
    unit : bool
        Also require ``| |q| - 1 | <= tolerance`` (a rotation); else only a nonzero norm.
    name : str
        The argument's name, for the message.
    tolerance : float
        Largest accepted ``| |q| - 1 |``.

    Returns
    -------
    numpy.ndarray
        ``q`` as floats, of its own shape.

    Raises
    ------
    ValueError
        For a wrong shape, a non-finite component, a zero quaternion or (``unit``) a norm
        off 1, naming ``name`` and the batch index.
    """
    values = _as_float(q, name)
    rows = _check_rows(values, name, 4, "quaternions (w, x, y, z)")
    norm = np.linalg.norm(rows, axis=1)
    bad = np.abs(norm - 1.0) > tolerance if unit else norm == 0.0
    if bad.any():
        i = int(np.argmax(bad))
        wanted = f"not a unit quaternion (| |q| - 1 | > {tolerance:g})" if unit else "a zero quaternion"
        raise ValueError(f"{_where(name, values.shape[:-1], i)}: {rows[i].tolist()} has norm {norm[i]:.6g}: {wanted}")
    return values


def check_dual_quaternion(
    dq: object, unit: bool = True, name: str = "dq", tolerance: float = UNIT_TOLERANCE
) -> np.ndarray:
    """Check dual quaternions ``(Q_r, Q_d)`` (Seleem et al. 2020, eqs. 9-10).

    A unit dual quaternion has ``|Q_r| = 1`` and ``Q_r . Q_d = 0``; then
    ``Q_d = 0.5 (0, p) Q_r`` for the translation ``p``.

    Parameters
    ----------
    dq : array_like
        One dual quaternion ``(8,)`` or a batch ``(..., 8)``.
    unit : bool
        Also require ``| |Q_r| - 1 | <= tolerance`` and ``|Q_r . Q_d| <= tolerance`` (a rigid
        transform); else only a nonzero real part.
    name : str
        The argument's name, for the message.
    tolerance : float
        Largest accepted ``| |Q_r| - 1 |`` and ``|Q_r . Q_d|`` (units of ``Q_d``: metres / 2).

    Returns
    -------
    numpy.ndarray
        ``dq`` as floats, of its own shape.

    Raises
    ------
    ValueError
        For a wrong shape, a non-finite component, a zero real part or (``unit``) a dual
        quaternion that is not unit, naming ``name`` and the batch index.
    """
    values = _as_float(dq, name)
    rows = _check_rows(values, name, 8, "dual quaternions (Q_r, Q_d)")
    norm = np.linalg.norm(rows[:, :4], axis=1)
    if not unit:
        bad = norm == 0.0
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{_where(name, values.shape[:-1], i)}: the real part is zero")
        return values
    dot = np.einsum("ij,ij->i", rows[:, :4], rows[:, 4:])
    bad_norm = np.abs(norm - 1.0) > tolerance
    bad_dot = np.abs(dot) > tolerance
    if (bad_norm | bad_dot).any():
        i = int(np.argmax(bad_norm | bad_dot))
        where = _where(name, values.shape[:-1], i)
        if bad_norm[i]:
            raise ValueError(
                f"{where}: real part {rows[i, :4].tolist()} has norm {norm[i]:.6g}: not a unit dual quaternion "
                f"(| |Q_r| - 1 | > {tolerance:g})"
            )
        raise ValueError(
            f"{where}: Q_r . Q_d = {dot[i]:.3g}: not a unit dual quaternion (the dual part must be "
            f"orthogonal to the real part within {tolerance:g})"
        )
    return values


def check_configuration(
    arm: ArmModel,
    q: object,
    name: str = "q",
    bounds: bool = True,
    batch: bool = False,
    tolerance: float = BOUND_TOLERANCE,
) -> np.ndarray:
    """Check configurations of ``arm``: shape, finite values and (``bounds``) the arm's bounds.

    Periodic variables (e.g. the ``phi`` of a CC section) are not bound-checked: the
    kinematics are 2 pi-periodic in them.

    Parameters
    ----------
    arm : ArmModel
        The arm whose :attr:`~optikin.arms.base.ArmModel.config_names` and bounds apply.
    q : array_like
        One configuration ``(n_config,)``; with ``batch`` also ``(N, n_config)``. SI units.
    name : str
        The argument's name, for the message.
    bounds : bool
        Whether to require ``lower <= q <= upper`` (to ``tolerance``).
    batch : bool
        Whether a batch ``(N, n_config)`` is accepted.
    tolerance : float
        Slack on the bounds, relative to each variable's range (absolute for a fixed variable).

    Returns
    -------
    numpy.ndarray
        ``q`` as floats, of its own shape.

    Raises
    ------
    ValueError
        For a wrong shape, a non-finite value or a value outside the bounds, naming ``name``,
        the sample (for a batch) and the variable.
    """
    values = _as_float(q, name)
    n = arm.n_config
    shapes = f"({n},) or (N, {n})" if batch else f"({n},)"
    if values.shape != (n,) and not (batch and values.ndim == 2 and values.shape[1] == n):
        hint = "" if batch or values.ndim != 2 or values.shape[1] != n else "; for a batch use arm.evaluate(name, Q)"
        raise ValueError(
            f"{name}: expected a configuration of {arm.name} of shape {shapes} "
            f"({', '.join(arm.config_names)}), got shape {values.shape}{hint}"
        )
    rows = values.reshape(-1, n)

    def where(i: int) -> str:
        return f"{name}[{i}]" if values.ndim == 2 else name

    bad = ~np.isfinite(rows)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise ValueError(f"{where(i)}: {arm.config_names[j]} = {rows[i, j]} is not a finite number")
    if bounds:
        span = arm.upper - arm.lower
        slack = tolerance * np.where(span > 0, span, 1.0)
        outside = ((rows < arm.lower - slack) | (rows > arm.upper + slack)) & ~arm.periodic
        if outside.any():
            i, j = (int(k) for k in np.argwhere(outside)[0])
            raise ValueError(
                f"{where(i)}: {arm.config_names[j]} = {rows[i, j]:.6g} outside its bounds "
                f"[{arm.lower[j]:.6g}, {arm.upper[j]:.6g}]"
            )
    return values


def check_parameter(value: object, field: str, positive: bool = False, size: int | None = None) -> np.ndarray:
    """Check a numeric model parameter: numbers, finite, optionally positive and of a given length.

    Parameters
    ----------
    value : array_like
        A number or a vector of numbers.
    field : str
        The parameter's name (``section_lengths``); an entry of a vector is named
        ``section_lengths.0``.
    positive : bool
        Whether every entry must be above zero.
    size : int, optional
        The length a vector must have; ``None``: any length (a scalar stays a scalar).

    Returns
    -------
    numpy.ndarray
        ``value`` as floats (0-d for a scalar).

    Raises
    ------
    ParameterError
        Naming the field (and the entry of a vector).
    """
    try:
        values = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(field, f"expected numbers, got {value!r}") from None
    if values.ndim > 1 or (size is not None and values.shape != (size,)):
        wanted = f"{size} numbers" if size is not None else "a number or a list of numbers"
        raise ParameterError(field, f"expected {wanted}, got {value!r}")
    flat = np.atleast_1d(values)
    for i, v in enumerate(flat):
        entry = f"{field}.{i}" if values.ndim == 1 else field
        if not np.isfinite(v):
            raise ParameterError(entry, f"not a finite number ({v})")
        if positive and not v > 0:
            raise ParameterError(entry, f"must be positive, got {v:g}")
    return values
