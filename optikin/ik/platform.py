"""CBHA platforms: leg lengths ``(q_1k, q_2k, q_3k)`` -> ``(Z_k, theta_k, psi_k)`` (seed 004, section IV-A).

Seed 004 calls this the forward model of an inter-vertebra and solves it with
a neural network because inverting its eqs. (7)-(9) numerically is "computationally
intensive". Here each platform ``k`` is its own 3 x 3 least-squares problem

    r(Z, theta, psi; q) = legs_k(Z, theta, psi) - q,

with ``legs_k`` the arm's leg lengths of eqs. (3)-(6) (equal to the printed eqs.
(7)-(9), :func:`optikin.arms.cbha.printed_leg_lengths`) and the bounds on
``(Z_k, theta_k, psi_k)`` that Table I implies (:func:`optikin.arms.cbha.platform_bounds`).
The 16 platforms of a sample are independent: every platform is solved for all
samples at once by the backend's :meth:`solve_many` (for ``gauss_newton``, one call into its
compiled C, :mod:`optikin.native.ik`, with the same answers), and a sample is ``ok`` when
all 16 of its platforms are.

Two helpers serve the hybrid networks of seed 004 (kinds ``nn_fkm`` and ``nn_ikm``):
:func:`linearised_start`, a starting point from the leg lengths themselves, and
:func:`realise`, what the arm does with commanded leg lengths.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from optikin.arms.cbha import PLATFORM_LEG_LENGTHS, CBHAArm
from optikin.native.ik import solve_many
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter
from optikin.solvers.base import SolutionBatch
from optikin.status import Status

CLIP_TOLERANCE = 1e-9
"""A commanded length counts as clipped when it leaves Table I by more than this [m] (a solver's
constraint tolerance is not a clip)."""
STATUS_PRIORITY = (Status.FAILED, Status.TIMEOUT, Status.NOT_CONVERGED, Status.UNREACHABLE, Status.OK)
"""A sample takes the first of these statuses that any of its platforms has."""


def platform_problems(arm: CBHAArm, tolerance: float) -> list[LeastSquaresProblem]:
    """One least-squares problem per platform (module docstring).

    Parameters
    ----------
    arm:
        The CBHA.
    tolerance:
        Leg-length error ``||r||`` [m] counted as solved.

    Returns
    -------
    list of LeastSquaresProblem
        Problem ``k``: variables ``x = (Z_k, theta_k, psi_k)`` within the arm's bounds, data the
        leg lengths ``(q_1k, q_2k, q_3k)`` [m], residual ``legs_k(x) - q`` [m].
    """
    radii = arm.geometry.radii
    problems = []
    for k in range(arm.geometry.n_platforms):
        x, q = ca.SX.sym("x", 3), ca.SX.sym("q", 3)
        legs = PLATFORM_LEG_LENGTHS(x[0], x[1], x[2], radii[k], radii[k + 1])
        residual = ca.Function(f"cbha_platform{k + 1}_legs", [x, q], [legs - q], ["x", "q"], ["r"])
        block = slice(3 * k, 3 * k + 3)
        problems.append(
            LeastSquaresProblem(
                residual,
                arm.lower[block],
                arm.upper[block],
                np.zeros(3, dtype=bool),
                tolerance=tolerance,
                name=f"cbha_platform{k + 1}",
                variable_names=arm.config_names[block],
            )
        )
    return problems


def solve_platforms(
    adapter: NonlinearAdapter,
    problems: list[LeastSquaresProblem],
    legs: np.ndarray,
    start: np.ndarray,
    warm_start: bool = False,
) -> SolutionBatch:
    """Every platform of every sample with one ``nonlinear`` adapter.

    Parameters
    ----------
    adapter:
        A ``nonlinear`` backend's adapter; each platform is one :meth:`solve_many` call over the samples (in
        C for ``gauss_newton``, :func:`optikin.native.ik.solve_many`).
    problems:
        The platform problems of :func:`platform_problems`.
    legs:
        Leg lengths ``(N, 3 n_platforms)`` [m].
    start:
        Start configuration ``(3 n_platforms,)`` or one per sample ``(N, 3 n_platforms)``.
    warm_start:
        Start each sample from the previous sample's solution (a trajectory).

    Returns
    -------
    SolutionBatch
        Configurations ``(N, 3 n_platforms)``; a sample's status is the worst of its platforms'
        (:data:`STATUS_PRIORITY`), its iterations and time add up over them, its residual is the largest.
    """
    reports = [
        solve_many(adapter, problem, start[..., 3 * k : 3 * k + 3], legs[:, 3 * k : 3 * k + 3], warm_start)
        for k, problem in enumerate(problems)
    ]
    statuses = np.array([r.status for r in reports])  # (platform, sample)
    status: list[str] = [next(s for s in STATUS_PRIORITY if s in column) for column in statuses.T]
    messages = []
    for i in range(len(legs)):
        bad = [f"platform {k + 1}: {r.messages[i]}" for k, r in enumerate(reports) if r.messages[i]]
        messages.append("; ".join(bad))
    return SolutionBatch(
        x=np.hstack([r.x for r in reports]),
        status=status,
        iterations=np.sum([r.iterations for r in reports], axis=0),
        residual=np.max([r.residual for r in reports], axis=0),
        seconds=np.sum([r.seconds for r in reports], axis=0),
        messages=messages,
        batched=all(r.batched for r in reports),
    )


def linearised_start(arm: CBHAArm, legs: np.ndarray) -> np.ndarray:
    """Starting configurations ``(N, 48)`` from leg lengths ``(N, 48)``: eqs. (7)-(9) linearised.

    For small angles ``q_1 - (q_2 + q_3)/2 ~ 3/2 r_{k+1} sin theta`` and
    ``q_2 - q_3 ~ sqrt(3) r_{k+1} sin psi cos theta``, and ``Z ~ mean(q)``; the sines are
    clipped to 0.9 so that a far-off length still gives a finite start.
    """
    legs = np.atleast_2d(np.asarray(legs, dtype=float))
    L = legs.reshape(len(legs), -1, 3)
    q1, q2, q3 = L[..., 0], L[..., 1], L[..., 2]
    r_upper = arm.geometry.radii[1:]
    theta = np.arcsin(np.clip((q1 - 0.5 * (q2 + q3)) / (1.5 * r_upper), -0.9, 0.9))
    psi = np.arcsin(np.clip((q2 - q3) / (np.sqrt(3.0) * r_upper * np.cos(theta)), -0.9, 0.9))
    return np.stack([(q1 + q2 + q3) / 3.0, theta, psi], axis=-1).reshape(len(legs), -1)


@dataclass
class Realised:
    """What the arm does with commanded leg lengths (``clipped``: per sample, whether a length left
    Table I by more than :data:`CLIP_TOLERANCE`; ``report``: the platform solve of the applied lengths)."""

    commanded: np.ndarray
    clipped: np.ndarray
    configurations: np.ndarray
    tip: np.ndarray
    report: SolutionBatch


def realise(
    arm: CBHAArm, configurations: np.ndarray, adapter: NonlinearAdapter, problems: list[LeastSquaresProblem]
) -> Realised:
    """The leg lengths of ``configurations`` (eqs. 7-9) clipped to Table I, as the actuators would,
    the pose they produce (every platform solved by ``adapter`` from :func:`linearised_start`)
    and its tip (eq. 5). A configuration with a non-finite value, or applied lengths whose
    platform solve is not ``ok``, gives a non-finite pose and tip."""
    configurations = np.atleast_2d(np.asarray(configurations, dtype=float))
    finite = np.all(np.isfinite(configurations), axis=1)
    commanded = np.full((len(configurations), 3 * arm.geometry.n_platforms), np.nan)
    if finite.any():
        commanded[finite] = arm.evaluate("leg_lengths", configurations[finite], check=False).reshape(
            int(finite.sum()), -1
        )
    lo, hi = arm.leg_limits()
    applied = np.where(finite[:, None], np.clip(commanded, lo, hi), 0.5 * (lo + hi))
    report = solve_platforms(adapter, problems, applied, linearised_start(arm, applied))
    solved = finite & (np.array(report.status) == Status.OK)
    Q = np.where(solved[:, None], report.x, np.nan)
    tip = np.full((len(Q), 3), np.nan)
    if solved.any():
        tip[solved] = arm.evaluate("fk_position", Q[solved])
    return Realised(
        commanded=commanded,
        clipped=np.any(np.abs(applied - commanded) > CLIP_TOLERANCE, axis=1),
        configurations=Q,
        tip=tip,
        report=report,
    )
