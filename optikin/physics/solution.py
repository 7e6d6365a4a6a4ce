"""The equilibrium of a rod as the solvers return it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from optikin.status import Status


@dataclass(frozen=True)
class RodSolution:
    """One static equilibrium, on the nodes of the solver's grid.

    At a disk between segments the node carries the state just after the disk (the
    wrench there includes the jump of the actuators ending at the disk); the last
    node is the tip, just before the tip loads.

    Attributes
    ----------
    s : numpy.ndarray
        ``(K,)`` reference arc length of the nodes [m].
    positions : numpy.ndarray
        ``(K, 3)`` centre line [m], global frame.
    orientations : numpy.ndarray
        ``(K, 4)`` unit quaternions ``(w, x, y, z)`` of the material frames.
    n, m : numpy.ndarray
        ``(K, 3)`` internal force [N] and moment [N m] of the rod, global frame.
    base_wrench : numpy.ndarray
        ``(6,)`` ``(n(0), m(0))``: the rod's wrench just after the clamp (the BVP's unknown).
    residual_norm : float
        Euclidean norm of the tip residual ``(N(L) - F_tip, M(L) - C_tip)`` [N, N m mixed].
    status : str
        ``"ok"`` when the boundary conditions hold to the solver's tolerance, else ``"failed"``.
    iterations : int
        Newton (or IPOPT) iterations.
    message : str
        Why it failed, or empty.
    """

    s: np.ndarray
    positions: np.ndarray
    orientations: np.ndarray
    n: np.ndarray
    m: np.ndarray
    base_wrench: np.ndarray
    residual_norm: float
    status: Literal[Status.OK, Status.FAILED]
    iterations: int = 0
    message: str = ""

    @property
    def ok(self) -> bool:
        """``status == "ok"``."""
        return self.status == Status.OK

    @property
    def tip_position(self) -> np.ndarray:
        """``(3,)`` [m]."""
        return self.positions[-1]

    @classmethod
    def from_states(
        cls,
        s: np.ndarray,
        states: np.ndarray,
        residual_norm: float,
        tolerance: float,
        iterations: int = 0,
        message: str = "",
    ) -> RodSolution:
        """From the ``(13, K)`` states ``(p, q, n, m)``; failed unless ``residual_norm <= tolerance``."""
        X = np.asarray(states, dtype=float).T
        ok = bool(np.isfinite(residual_norm) and residual_norm <= tolerance and np.all(np.isfinite(X)))
        if not ok and not message:
            message = f"tip residual {residual_norm:.3g} above the tolerance {tolerance:.3g}"
        return cls(
            s=np.asarray(s, dtype=float),
            positions=X[:, 0:3].copy(),
            orientations=X[:, 3:7].copy(),
            n=X[:, 7:10].copy(),
            m=X[:, 10:13].copy(),
            base_wrench=X[0, 7:13].copy(),
            residual_norm=float(residual_norm),
            status=Status.OK if ok else Status.FAILED,
            iterations=iterations,
            message="" if ok else message,
        )
