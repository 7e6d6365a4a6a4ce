"""CBHA platforms: leg lengths ``(q_1k, q_2k, q_3k)`` -> ``(Z_k, theta_k, psi_k)`` (seed 004, section IV-A).

Seed 004 calls this the forward model of an inter-vertebra and solves it with
a neural network because inverting its eqs. (7)-(9) numerically is "computationally
intensive". Here each platform ``k`` is its own 3 x 3 least-squares problem

    r(Z, theta, psi; q) = legs_k(Z, theta, psi) - q,

with ``legs_k`` the arm's leg lengths of eqs. (3)-(6) (equal to the printed eqs.
(7)-(9), :func:`optikin.arms.cbha.printed_leg_lengths`) and the bounds on
``(Z_k, theta_k, psi_k)`` that Table I implies (:func:`optikin.arms.cbha.platform_bounds`).
The 16 platforms of a sample are independent: every platform is solved for all
samples at once by the backend's :meth:`solve_many`, and a sample is ``ok`` when
all 16 of its platforms are.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.arms.cbha import PLATFORM_LEG_LENGTHS, CBHAArm
from optikin.solvers.nonlinear import BatchReport, LeastSquaresProblem, NonlinearAdapter

STATUS_PRIORITY = ("failed", "timeout", "not_converged", "unreachable", "ok")
"""A sample takes the first of these statuses that any of its platforms has."""


def platform_problems(arm: CBHAArm, tolerance: float) -> list[LeastSquaresProblem]:
    """One problem per platform: ``x = (Z_k, theta_k, psi_k)``, data ``q = (q_1k, q_2k, q_3k)``."""
    radii = arm.geometry.radii
    problems = []
    for k in range(arm.geometry.n_platforms):
        x, q = ca.SX.sym("x", 3), ca.SX.sym("q", 3)
        legs = PLATFORM_LEG_LENGTHS(x[0], x[1], x[2], radii[k], radii[k + 1])
        residual = ca.Function(f"cbha_platform{k + 1}_legs", [x, q], [legs - q], ["x", "q"], ["r"])
        block = slice(3 * k, 3 * k + 3)
        problems.append(LeastSquaresProblem(residual, arm.lower[block], arm.upper[block], np.zeros(3, dtype=bool),
                                            tolerance=tolerance, name=f"cbha_platform{k + 1}",
                                            variable_names=arm.config_names[block]))
    return problems


def solve_platforms(adapter: NonlinearAdapter, problems: list[LeastSquaresProblem], legs: np.ndarray,
                    start: np.ndarray, warm_start: bool = False) -> BatchReport:
    """Every platform of every sample; ``legs`` is ``(N, 3 * platforms)``, ``start`` one configuration or N.

    A sample's iterations and time add up over its platforms, its residual is the largest.
    """
    reports = [adapter.solve_many(problem, start[..., 3 * k: 3 * k + 3], legs[:, 3 * k: 3 * k + 3], warm_start)
               for k, problem in enumerate(problems)]
    statuses = np.array([r.status for r in reports])  # (platform, sample)
    status = [next(s for s in STATUS_PRIORITY if s in column) for column in statuses.T]
    messages = []
    for i in range(len(legs)):
        bad = [f"platform {k + 1}: {r.messages[i]}" for k, r in enumerate(reports) if r.messages[i]]
        messages.append("; ".join(bad))
    return BatchReport(
        x=np.hstack([r.x for r in reports]),
        status=status,
        iterations=np.sum([r.iterations for r in reports], axis=0),
        residual=np.max([r.residual for r in reports], axis=0),
        time=np.sum([r.time for r in reports], axis=0),
        messages=messages,
        batched=all(r.batched for r in reports),
    )
