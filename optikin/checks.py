"""Validators of the inputs of the Python API, in the style of pytransform3d's ``check_*``: one per concept.

Each ``check_*`` function returns its input as a float array when it is usable and raises
:class:`TypeError` (not numbers: a string, ``None``, a complex or boolean value) or
:class:`ValueError` (a wrong shape, a non-finite entry, a magnitude or norm out of range)
naming the argument and the entry:

* :func:`check_numbers`: real numbers (integers or floats), as a float array;
* :func:`check_shape`: the trailing shape, e.g. ``(..., 4)``;
* :func:`check_finite`: no NaN or infinity;
* :func:`check_magnitude`: every entry within ``+-`` a plausible limit (:data:`MAX_MAGNITUDE`);
* :func:`check_vectors`: finite vectors ``(..., n)``, optionally of unit norm or nonzero;
* :func:`check_quaternion`: shape ``(..., 4)``, finite, unit norm within :data:`UNIT_TOLERANCE`;
* :func:`check_dual_quaternion`: shape ``(..., 8)``, finite, a unit real part and a dual
  part orthogonal to it (``Q_r . Q_d = 0``, Seleem et al. 2020, eqs. 9-10);
* :func:`check_rotation_matrix`: ``(..., 3, 3)``, finite, ``R^T R = I`` and ``det R = +1``;
* :func:`check_configuration`: configurations of an arm, finite, inside the arm's bounds (or
  plausibly near them) with periodic angles excepted;
* :func:`check_parameter`: a model parameter (scalar or vector), a finite number, optionally
  positive and below a physical bound; raises :class:`ParameterError`, which carries the
  parameter's field name.

They are numpy-only and meant for the public entry points (the policy: ``docs/conventions.md``,
"Checked inputs"); inner loops call the unchecked functions (``check=False``) or the raw CasADi
Functions.
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from optikin.arms.base import ArmModel

UNIT_TOLERANCE = 1e-6
"""The one tolerance on unit norms: largest accepted ``| |q| - 1 |`` of a quaternion (and ``|Q_r . Q_d|`` of a
dual quaternion, ``| R^T R - I |`` of a rotation matrix, ``| |n| - 1 |`` of a unit axis)."""
BOUND_TOLERANCE = 1e-9
"""Default slack on an arm's bounds, relative to each variable's range (absolute for a fixed variable)."""
MAX_MAGNITUDE = 1e6
"""Largest plausible angle [rad] or translation [m] taken by the algebra: beyond it an angle has lost a
turn's worth of digits to rounding (the spacing of doubles near 1e6 is 1e-10) and a length is a unit mistake."""
NEAR_SPANS = 1.0
"""How far outside its bounds a variable of one configuration may lie in a numeric call of an arm Function
(:func:`check_configuration` with ``within="near"``), in multiples of its range: a solver's trial point
or a reference step past a bound passes, ``theta = 10`` rad against a bound of 2.09 rad does not."""
PLAUSIBLE_SPANS = 10.0
"""How far outside its bounds a configuration variable may plausibly lie, in multiples of its range
(:func:`check_configuration` with ``within="plausible"``): a solver's or a network's overshoot passes,
millimetres or degrees given for metres or radians do not."""


class ParameterError(ValueError):
    """An unusable model parameter: ``field`` its dotted name (``section_lengths.0``), ``message`` what is wrong."""

    def __init__(self, field: str, message: str) -> None:
        self.field, self.message = field, message
        super().__init__(f"{field}: {message}")


class ParameterTypeError(ParameterError, TypeError):
    """A model parameter that is not a number (a string, a bool, ``None``): both a :class:`TypeError` and a
    :class:`ParameterError`."""


def _where(name: str, shape: tuple[int, ...], flat_index: int) -> str:
    """``name[i, j]`` for entry ``flat_index`` of a batch of shape ``shape`` (``name`` alone when unbatched)."""
    if not shape:
        return name
    index = np.unravel_index(flat_index, shape)
    return f"{name}[{', '.join(str(int(i)) for i in index)}]"


def _describe(value: object) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 40 else text[:37] + '...'}"


def check_numbers(value: object, name: str) -> np.ndarray:
    """Check that ``value`` holds real numbers (integers or floats) and return them as floats.

    Parameters
    ----------
    value : array_like
        A number, a (nested) sequence of numbers or an array.
    name : str
        The argument's name, for the message.

    Returns
    -------
    numpy.ndarray
        ``value`` as a float array of its own shape (the same object for a float array).

    Raises
    ------
    TypeError
        For a string, ``None``, a boolean, a complex number or anything else that is not real numbers.
    ValueError
        For a ragged sequence.
    """
    if isinstance(value, np.ndarray) and value.dtype == np.float64:
        return value
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name}: expected numbers, got {_describe(value)}")
    try:
        array = np.asarray(value)
    except ValueError:
        raise ValueError(f"{name}: expected an array of numbers, got a ragged sequence {_describe(value)}") from None
    if array.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected real numbers, got {_describe(value)} (dtype {array.dtype})")
    return array.astype(float, copy=False)


def check_shape(values: np.ndarray, name: str, trailing: tuple[int, ...], what: str = "an array") -> np.ndarray:
    """Check that ``values`` has the trailing shape ``trailing`` (any batch shape before it).

    Parameters
    ----------
    values : numpy.ndarray
        The array.
    name : str
        The argument's name, for the message.
    trailing : tuple of int
        The required last dimensions, e.g. ``(4,)`` or ``(3, 3)``.
    what : str
        What the array holds, for the message (``"quaternions (w, x, y, z)"``).

    Returns
    -------
    numpy.ndarray
        ``values``.

    Raises
    ------
    ValueError
        Naming ``name``, the shape wanted and the shape given.
    """
    k = len(trailing)
    if values.ndim < k or values.shape[values.ndim - k :] != trailing:
        wanted = ", ".join(str(t) for t in trailing)
        raise ValueError(
            f"{name}: expected {what} of shape ({wanted}{',' if k == 1 else ''}) or (..., {wanted}), "
            f"got shape {values.shape}"
        )
    return values


def check_finite(values: np.ndarray, name: str, width: int = 1) -> np.ndarray:
    """Check that every entry of ``values`` is finite.

    Parameters
    ----------
    values : numpy.ndarray
        Float array.
    name : str
        The argument's name, for the message.
    width : int
        Length of the trailing element (4 for quaternions): the message names the element
        ``name[i]`` and shows it; 1 names the entry.

    Returns
    -------
    numpy.ndarray
        ``values``.

    Raises
    ------
    ValueError
        Naming ``name`` and the first element with a NaN or an infinity.
    """
    if np.isfinite(values).all():
        return values
    rows = values.reshape(-1, width)
    i = int(np.argmax(~np.isfinite(rows).all(axis=1)))
    shown = rows[i].tolist() if width > 1 else rows[i, 0]
    batch = values.shape[:-1] if width > 1 else values.shape
    kind = "has a non-finite component" if width > 1 else "is not a finite number"
    raise ValueError(f"{_where(name, batch, i)}: {shown} {kind}")


def check_magnitude(values: np.ndarray, name: str, limit: float = MAX_MAGNITUDE, unit: str = "") -> np.ndarray:
    """Check that every entry of ``values`` lies within ``[-limit, limit]`` (NaN fails too).

    Parameters
    ----------
    values : numpy.ndarray
        Float array.
    name : str
        The argument's name, for the message.
    limit : float
        The largest plausible magnitude.
    unit : str
        The entries' unit, for the message (``"rad"``).

    Returns
    -------
    numpy.ndarray
        ``values``.

    Raises
    ------
    ValueError
        Naming ``name`` and the first entry out of range.
    """
    if (np.abs(values) <= limit).all():
        return values
    check_finite(values, name)
    flat = values.reshape(-1)
    i = int(np.argmax(~(np.abs(flat) <= limit)))
    suffix = f" {unit}" if unit else ""
    raise ValueError(
        f"{_where(name, values.shape, i)}: {flat[i]:.6g}{suffix} is beyond the plausible magnitude {limit:g}{suffix}"
    )


def _check_rows(values: np.ndarray, name: str, width: int, what: str) -> np.ndarray:
    """``values`` of shape ``(..., width)`` with finite entries, as rows ``(M, width)``."""
    check_shape(values, name, (width,), what)
    check_finite(values, name, width)
    return values.reshape(-1, width)


def _squares_within(values: np.ndarray, width: int, tolerance: float | None, orthogonal: float | None = None) -> bool:
    """Fast acceptance of quaternions (``width`` 4) or dual quaternions (8): True when every element has
    a finite, nonzero norm of its first 4 components (``| |q| - 1 | <= tolerance`` unless ``tolerance`` is
    None) and, with ``orthogonal``, ``|Q_r . Q_d| <= orthogonal``; False sends the caller to the detailed
    check that names the bad element (NaN fails every comparison)."""
    if values.ndim == 0 or values.shape[-1] != width:
        return False
    real = values[..., :4]
    squares = np.einsum("...i,...i->...", real, real)
    if tolerance is None:
        ok = bool(((squares > 0.0) & (squares < np.inf)).all()) and bool(np.isfinite(values).all())
    else:
        ok = bool(((squares >= (1.0 - tolerance) ** 2) & (squares <= (1.0 + tolerance) ** 2)).all())
        ok = ok and (width == 4 or bool(np.isfinite(values[..., 4:]).all()))
    if ok and orthogonal is not None:
        ok = bool((np.abs(np.einsum("...i,...i->...", real, values[..., 4:])) <= orthogonal).all())
    return ok


def check_vectors(
    v: object, name: str, width: int = 3, unit: bool = False, nonzero: bool = False, tolerance: float = UNIT_TOLERANCE
) -> np.ndarray:
    """Check finite vectors ``(..., width)``; optionally of unit norm (within ``tolerance``) or nonzero.

    Parameters
    ----------
    v : array_like
        One vector ``(width,)`` or a batch ``(..., width)``.
    name : str
        The argument's name, for the message.
    width : int
        The number of components.
    unit : bool
        Require ``| |v| - 1 | <= tolerance`` (an axis).
    nonzero : bool
        Require ``|v| > 0`` (a direction).
    tolerance : float
        See ``unit``.

    Returns
    -------
    numpy.ndarray
        ``v`` as floats, of its own shape.

    Raises
    ------
    TypeError
        For values that are not numbers.
    ValueError
        For a wrong shape, a non-finite component, or a norm off 1 (``unit``) or zero (``nonzero``),
        naming ``name`` and the batch index.
    """
    values = check_numbers(v, name)
    rows = _check_rows(values, name, width, f"vectors of {width} components")
    if unit or nonzero:
        norm = np.linalg.norm(rows, axis=1)
        bad = np.abs(norm - 1.0) > tolerance if unit else norm == 0.0
        if bad.any():
            i = int(np.argmax(bad))
            wanted = f"not a unit vector (| |v| - 1 | > {tolerance:g})" if unit else "a zero vector has no direction"
            raise ValueError(
                f"{_where(name, values.shape[:-1], i)}: {rows[i].tolist()} has norm {norm[i]:.6g}: {wanted}"
            )
    return values


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
    TypeError
        For values that are not numbers.
    ValueError
        For a wrong shape, a non-finite component, a zero quaternion or (``unit``) a norm
        off 1, naming ``name`` and the batch index.
    """
    values = check_numbers(q, name)
    if _squares_within(values, 4, tolerance if unit else None):
        return values
    rows = _check_rows(values, name, 4, "quaternions (w, x, y, z)")
    norm = np.linalg.norm(rows, axis=1)
    bad = np.abs(norm - 1.0) > tolerance if unit else norm == 0.0
    if bad.any():
        i = int(np.argmax(bad))
        wanted = f"not a unit quaternion (| |q| - 1 | > {tolerance:g})" if unit else "a zero quaternion"
        raise ValueError(f"{_where(name, values.shape[:-1], i)}: {rows[i].tolist()} has norm {norm[i]:.6g}: {wanted}")
    return values


def check_dual_quaternion(
    dq: object, unit: bool = True, name: str = "dq", tolerance: float = UNIT_TOLERANCE, orthogonal: bool = True
) -> np.ndarray:
    """Check dual quaternions ``(Q_r, Q_d)`` (Seleem et al. 2020, eqs. 9-10).

    A unit dual quaternion has ``|Q_r| = 1`` and ``Q_r . Q_d = 0``; then
    ``Q_d = 0.5 (0, p) Q_r`` for the translation ``p``.

    Parameters
    ----------
    dq : array_like
        One dual quaternion ``(8,)`` or a batch ``(..., 8)``.
    unit : bool
        Also require ``| |Q_r| - 1 | <= tolerance`` and (``orthogonal``) ``|Q_r . Q_d| <= tolerance``
        (a rigid transform); else only a nonzero real part.
    name : str
        The argument's name, for the message.
    tolerance : float
        Largest accepted ``| |Q_r| - 1 |`` and ``|Q_r . Q_d|`` (units of ``Q_d``: metres / 2).
    orthogonal : bool
        With ``unit``, also require the dual part orthogonal to the real part (what a screw needs; a
        translation ``2 vec(Q_d Q_r*)`` is defined without it).

    Returns
    -------
    numpy.ndarray
        ``dq`` as floats, of its own shape.

    Raises
    ------
    TypeError
        For values that are not numbers.
    ValueError
        For a wrong shape, a non-finite component, a zero real part or (``unit``) a dual
        quaternion that is not unit, naming ``name`` and the batch index.
    """
    values = check_numbers(dq, name)
    if _squares_within(values, 8, tolerance if unit else None, tolerance if unit and orthogonal else None):
        return values
    rows = _check_rows(values, name, 8, "dual quaternions (Q_r, Q_d)")
    norm = np.linalg.norm(rows[:, :4], axis=1)
    if not unit:
        bad = norm == 0.0
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{_where(name, values.shape[:-1], i)}: the real part is zero")
        return values
    bad_norm = np.abs(norm - 1.0) > tolerance
    dot = np.einsum("ij,ij->i", rows[:, :4], rows[:, 4:]) if orthogonal else np.zeros(len(rows))
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


def check_rotation_matrix(R: object, name: str = "R", tolerance: float = UNIT_TOLERANCE) -> np.ndarray:
    """Check rotation matrices: shape ``(..., 3, 3)``, finite, ``|R^T R - I| <= tolerance`` and ``det R > 0``.

    Parameters
    ----------
    R : array_like
        One matrix ``(3, 3)`` or a batch ``(..., 3, 3)``.
    name : str
        The argument's name, for the message.
    tolerance : float
        Largest accepted entry of ``|R^T R - I|``.

    Returns
    -------
    numpy.ndarray
        ``R`` as floats, of its own shape.

    Raises
    ------
    TypeError
        For values that are not numbers.
    ValueError
        For a wrong shape, a non-finite entry, a matrix that is not orthonormal or a reflection,
        naming ``name`` and the batch index.
    """
    values = check_numbers(R, name)
    check_shape(values, name, (3, 3), "rotation matrices")
    check_finite(values, name)
    mats = values.reshape(-1, 3, 3)
    residual = np.abs(np.einsum("kji,kjl->kil", mats, mats) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(mats)
    bad = (residual > tolerance) | (det <= 0.0)
    if bad.any():
        i = int(np.argmax(bad))
        why = (
            f"R^T R differs from the identity by {residual[i]:.3g} (> {tolerance:g})"
            if residual[i] > tolerance
            else f"det R = {det[i]:.6g}: a reflection"
        )
        raise ValueError(f"{_where(name, values.shape[:-2], i)}: not a rotation matrix: {why}")
    return values


SPANS = {"bounds": 0.0, "near": NEAR_SPANS, "plausible": PLAUSIBLE_SPANS, "finite": np.inf}
"""The intervals of :func:`configuration_limits`: how many ranges they reach past the bounds."""

_LIMITS: weakref.WeakKeyDictionary[Any, dict[tuple[str, float], tuple[np.ndarray, ...]]] = weakref.WeakKeyDictionary()
"""The intervals of :func:`configuration_limits` per arm, computed once (recomputed when a bound array is replaced)."""


def configuration_limits(
    arm: ArmModel, within: str = "bounds", tolerance: float = BOUND_TOLERANCE
) -> tuple[np.ndarray, np.ndarray]:
    """The interval each configuration variable of ``arm`` must lie in, for :func:`check_configuration`.

    Parameters
    ----------
    arm : ArmModel
        The arm whose bounds apply.
    within : {"bounds", "near", "plausible", "finite"}
        ``"bounds"``: the arm's bounds with a slack of ``tolerance`` times each variable's range;
        ``"near"``: the bounds widened by :data:`NEAR_SPANS` ranges on each side; ``"plausible"``: by
        :data:`PLAUSIBLE_SPANS` ranges; ``"finite"``: every finite value. A fixed variable's range is
        its magnitude (1 at 0). Except for ``"finite"``, a length the arm marks ``positive`` (a CC
        section's ``S``, a CBHA platform's ``Z``) must stay above 0, and a periodic variable (a CC
        section's ``phi``, whose bounds are one turn) is only held to
        ``+-`` :data:`MAX_MAGNITUDE`, as every angle of the algebra.
    tolerance : float
        See ``within``.

    Returns
    -------
    tuple of numpy.ndarray
        ``(low, high)``, each ``(n_config,)``.

    Raises
    ------
    ValueError
        For an unknown ``within``.
    """
    if within not in SPANS:
        raise ValueError(f"within: expected one of {', '.join(SPANS)}, got {within!r}")
    if within == "finite":
        largest = np.full(arm.n_config, np.finfo(float).max)
        return -largest, largest
    cached = _LIMITS.setdefault(arm, {}).get((within, tolerance))
    if cached is not None and cached[0] is arm.lower and cached[1] is arm.upper:
        return cached[2], cached[3]
    size = np.maximum(np.abs(arm.lower), np.abs(arm.upper))
    span = np.where(arm.upper > arm.lower, arm.upper - arm.lower, np.where(size > 0, size, 1.0))
    slack = (tolerance if within == "bounds" else SPANS[within]) * span
    low = np.where(arm.periodic, -MAX_MAGNITUDE, arm.lower - slack)
    high = np.where(arm.periodic, MAX_MAGNITUDE, arm.upper + slack)
    positive = getattr(arm, "positive", np.zeros(arm.n_config, dtype=bool))
    low = np.where(positive, np.maximum(low, np.finfo(float).tiny), low)
    _LIMITS[arm][(within, tolerance)] = (arm.lower, arm.upper, low, high)
    return low, high


def check_configuration(
    arm: ArmModel,
    q: object,
    name: str = "q",
    within: str = "bounds",
    batch: bool = False,
    tolerance: float = BOUND_TOLERANCE,
) -> np.ndarray:
    """Check configurations of ``arm``: numbers, shape, finite values inside the arm's bounds (or near them).

    Periodic variables (e.g. the ``phi`` of a CC section) are only held to ``+-`` :data:`MAX_MAGNITUDE`
    (:func:`configuration_limits`): the kinematics are 2 pi-periodic in them.

    Parameters
    ----------
    arm : ArmModel
        The arm whose :attr:`~optikin.arms.base.ArmModel.config_names` and bounds apply.
    q : array_like
        One configuration ``(n_config,)``; with ``batch`` also ``(..., n_config)``. SI units.
    name : str
        The argument's name, for the message.
    within : {"bounds", "near", "plausible", "finite"}
        ``"bounds"``: ``lower <= q <= upper`` (to ``tolerance``); ``"near"``: within :data:`NEAR_SPANS`
        ranges of the bounds (a numeric call of a kinematic arm Function); ``"plausible"``: within
        :data:`PLAUSIBLE_SPANS` ranges (a batch evaluation); ``"finite"``: any finite value (a
        constraint Function, evaluated at infeasible points too). See :func:`configuration_limits`.
    batch : bool
        Whether a batch ``(..., n_config)`` is accepted.
    tolerance : float
        Slack on the bounds, relative to each variable's range (absolute for a fixed variable).

    Returns
    -------
    numpy.ndarray
        ``q`` as floats, of its own shape.

    Raises
    ------
    TypeError
        For values that are not numbers (a string, ``None``, a complex value).
    ValueError
        For a wrong shape, a non-finite value or a value outside the interval, naming ``name``,
        the sample (for a batch) and the variable.
    """
    values = check_numbers(q, name)
    n = arm.n_config
    if values.shape != (n,) and not (batch and values.ndim >= 1 and values.shape[-1] == n):
        shapes = f"({n},) or (N, {n})" if batch else f"({n},)"
        hint = "" if batch or values.ndim != 2 or values.shape[1] != n else "; for a batch use arm.evaluate(name, Q)"
        raise ValueError(
            f"{name}: expected a configuration of {arm.name} of shape {shapes} "
            f"({', '.join(arm.config_names)}), got shape {values.shape}{hint}"
        )
    low, high = configuration_limits(arm, within, tolerance)
    rows = values.reshape(-1, n)
    if _within(rows, low, high):
        return values

    def where(i: int) -> str:
        return _where(name, values.shape[:-1], i)

    bad = ~np.isfinite(rows)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise ValueError(f"{where(i)}: {arm.config_names[j]} = {rows[i, j]} is not a finite number")
    i, j = (int(k) for k in np.argwhere((rows < low) | (rows > high))[0])
    value = f"{arm.config_names[j]} = {rows[i, j]:.6g}"
    if arm.periodic[j]:
        raise ValueError(f"{where(i)}: {value} is beyond the plausible magnitude {MAX_MAGNITUDE:g} of a periodic angle")
    bounds = f"[{arm.lower[j]:.6g}, {arm.upper[j]:.6g}]"
    positive = getattr(arm, "positive", np.zeros(n, dtype=bool))
    if positive[j] and not rows[i, j] > 0:
        raise ValueError(f"{where(i)}: {value} is not positive (a length; bounds {bounds})")
    if within == "bounds":
        raise ValueError(f"{where(i)}: {value} outside its bounds {bounds}")
    if within == "near":
        raise ValueError(f"{where(i)}: {value} outside its bounds {bounds} by more than {NEAR_SPANS:g} range")
    raise ValueError(
        f"{where(i)}: {value} is far outside its bounds {bounds} (more than {PLAUSIBLE_SPANS:g} ranges away: "
        "a unit mistake, millimetres or degrees for metres or radians?)"
    )


def _within(rows: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
    """Whether every row lies in ``[low, high]`` (NaN does not); a large batch by the extremes of contiguous
    columns, several times faster than comparing ``(N, n)`` against ``(n,)``."""
    if len(rows) <= 16:
        return bool((rows >= low).all() and (rows <= high).all())
    columns = np.ascontiguousarray(rows.T)
    return bool((columns.min(axis=1) >= low).all() and (columns.max(axis=1) <= high).all())


def check_parameter(
    value: object,
    field: str,
    positive: bool = False,
    size: int | None = None,
    maximum: float | None = None,
    unit: str = "",
    scalar: bool = False,
) -> np.ndarray:
    """Check a numeric model parameter: numbers, finite, optionally positive, below a bound and of a given length.

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
    maximum : float, optional
        The largest physically plausible magnitude ``|value|`` of an entry; ``None``: no bound.
    unit : str
        The parameter's unit, for the message (``"m"`` adds a hint about millimetres).
    scalar : bool
        Whether the parameter is one number (a list is refused naming it).

    Returns
    -------
    numpy.ndarray
        ``value`` as floats (0-d for a scalar).

    Raises
    ------
    ParameterTypeError
        For a value that is not numbers (a string, even of a number, a bool, ``None``), naming the field.
    ParameterError
        Naming the field (and the entry of a vector).
    """
    wanted = "one number" if scalar else f"{size} numbers" if size is not None else "a number or a list of numbers"
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if isinstance(v, (bool, np.bool_)):
                raise ParameterTypeError(f"{field}.{i}", f"expected a number, got {_describe(v)}")
    try:
        values = check_numbers(value, field)
    except TypeError:
        raise ParameterTypeError(field, f"expected {wanted}, got {_describe(value)}") from None
    except ValueError:
        raise ParameterError(field, f"expected numbers, got {value!r}") from None
    if values.ndim > 1 or (size is not None and values.shape != (size,)) or (scalar and values.ndim != 0):
        raise ParameterError(field, f"expected {wanted}, got {value!r}")
    flat = np.atleast_1d(values)
    for i, v in enumerate(flat):
        entry = f"{field}.{i}" if values.ndim == 1 else field
        if not np.isfinite(v):
            raise ParameterError(entry, f"not a finite number ({v})")
        if positive and not v > 0:
            raise ParameterError(entry, f"must be positive, got {v:g}")
        if maximum is not None and abs(v) > maximum:
            u = f" {unit}" if unit else ""
            hint = " (millimetres given for metres?)" if unit == "m" else ""
            raise ParameterError(entry, f"{v:g}{u} is beyond the physical bound {maximum:g}{u}{hint}")
    return values
