"""Backends ``ipopt`` and ``sqpmethod``: the problem as an NLP through CasADi ``nlpsol``.

With at most as many residuals as variables the residuals become equality
constraints (``nlpsol`` leaves ``g`` unbounded unless ``lbg``/``ubg``
are given, so both are set to zero) and the objective states the redundancy
preference,

    min 1/2 sum_i W_i^2 dist(x_i, x_ref,i)^2   s.t.   r(x, p) = 0,   lower <= x <= upper,

with ``dist^2 = 2 (1 - cos(x - x_ref))`` for angles that wrap (their bounds are
widened by a full turn and the result wrapped back); without weights the
objective is zero. With more residuals than variables, or for a problem that
is not exact (a penalised one, :mod:`optikin.solvers.nonlinear`), it is
``min 1/2 ||r(x, p)||^2`` within the bounds. A problem's ``constraints``
(e.g. CBHA leg lengths within Table I) are added as inequality rows of ``g``.

Preset options: :class:`IpoptOptions` and :class:`SqpmethodOptions`, whose
``settings`` are handed to the plugin (IPOPT options for ``ipopt``; ``sqpmethod``
options such as ``qpsol``, ``hessian_approximation`` for ``sqpmethod``); the plugin
is built once when the preset is validated, so an unknown name is reported as the
preset field ``options.settings.<name>``.
IPOPT runs with ``bound_relax_factor: 0``: with its default (1e-8 relative) a
solution at a bound (e.g. ``theta`` at its limit) came back outside it, and once
put back inside missed the target by about 2e-9 m, above the 1e-10 m tolerance (92
of the first 300 targets of the warm-started CC trajectory). The returned point is
still clipped to the bounds (a preset may relax them again) and then classified by
its own residual.
``limits.max_iterations`` becomes ``max_iter``; ``limits.time_limit`` becomes
IPOPT's ``max_wall_time`` (``sqpmethod`` has no time limit: its iteration limit
bounds the time, and a slower solve is reported ``timeout``).
"""

from __future__ import annotations

import re
import time
from typing import Any, Callable

import casadi as ca
import numpy as np
from pydantic import Field, ValidationError, field_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from optikin.errors import SolverError
from optikin.fastcall import BufferedFunction
from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter
from optikin.spec import LimitsSpec

QUIET_QP = {"print_iter": False, "print_header": False, "error_on_fail": False}


def nlp_of(problem: LeastSquaresProblem) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(nlp dict, lbx, ubx, lbg, ubg)`` (module docstring); parameters are ``(p, x_ref)``."""
    x, p, r, _ = problem.symbols
    x_ref = ca.SX.sym("x_ref", problem.n)
    if problem.exact and problem.m <= problem.n:
        if problem.weights is None:
            f = ca.SX(0)
        else:
            periodic = ca.DM(problem.periodic.astype(float))
            d2 = ca.if_else(periodic, 2 * (1 - ca.cos(x - x_ref)), (x - x_ref) ** 2)
            f = 0.5 * ca.dot(ca.DM(problem.weights**2), d2)
        g, lbg, ubg = r, np.zeros(problem.m), np.zeros(problem.m)
    else:
        f, g, lbg, ubg = 0.5 * ca.sumsqr(r), ca.SX(0, 1), np.zeros(0), np.zeros(0)
    if problem.constraints is not None:
        g = ca.vertcat(g, problem.constraints(x))
        lbg, ubg = np.concatenate([lbg, problem.constraint_lower]), np.concatenate([ubg, problem.constraint_upper])
    span = problem.upper - problem.lower
    lbx = np.where(problem.periodic, problem.lower - span, problem.lower)
    ubx = np.where(problem.periodic, problem.upper + span, problem.upper)
    return {"x": x, "p": ca.vertcat(p, x_ref), "f": f, "g": g}, lbx, ubx, lbg, ubg


def ipopt_options(limits: LimitsSpec, settings: dict[str, Any]) -> dict[str, Any]:
    """``nlpsol`` options of plugin ``ipopt``: the limits (module docstring), then the preset's ``settings``."""
    ipopt = {
        "print_level": 0,
        "sb": "yes",
        "tol": limits.tolerance,
        "bound_relax_factor": 0.0,
        "max_iter": limits.max_iterations,
        "max_wall_time": limits.time_limit,
    }
    ipopt.update(settings)
    return {"ipopt": ipopt, "print_time": False, "error_on_fail": False, "show_eval_warnings": False}


def sqpmethod_options(limits: LimitsSpec, settings: dict[str, Any]) -> dict[str, Any]:
    """``nlpsol`` options of plugin ``sqpmethod``: quiet qrqp QPs and the limits, then the preset's ``settings``."""
    options = {
        "qpsol": "qrqp",
        "qpsol_options": dict(QUIET_QP),
        "max_iter": limits.max_iterations,
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        "tol_pr": limits.tolerance,
    }
    options.update(settings)
    options.update({"print_time": False, "error_on_fail": False, "show_eval_warnings": False})
    return options


PluginOptions = Callable[[LimitsSpec, dict[str, Any]], dict[str, Any]]
PLUGIN_OPTIONS: dict[str, PluginOptions] = {"ipopt": ipopt_options, "sqpmethod": sqpmethod_options}
"""Plugin -> how its ``nlpsol`` options are made from a preset's limits and settings."""

UNKNOWN_OPTION = re.compile(r"(?:Unknown option|No such IPOPT option):?\s*'?([A-Za-z_0-9.]+)")


class SettingError(Exception):
    """A plugin refused a setting (``name``) or could not be built (``name`` empty)."""

    def __init__(self, name: str, message: str):
        super().__init__(message)
        self.name, self.message = name, message


def build_nlpsol(name: str, plugin: str, nlp: dict, options: dict[str, Any]) -> ca.Function:
    """``ca.nlpsol(name, plugin, nlp, options)``; a refused setting is a :class:`SettingError` naming it."""
    try:
        return ca.nlpsol(name, plugin, nlp, options)
    except RuntimeError as exc:
        text = str(exc)
        match = UNKNOWN_OPTION.search(text)
        if match:
            raise SettingError(match.group(1), f"not an option of {plugin}: {text.strip().splitlines()[-1]}") from None
        raise SettingError("", f"building {plugin} failed: {text}") from None


def checked_settings(plugin: str, settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` once the plugin accepted them on a one-variable NLP (default limits).

    Raises
    ------
    ValidationError
        Located at the refused setting's name (or at ``settings`` when the plugin fails otherwise).
    """
    x = ca.SX.sym("x")
    try:
        build_nlpsol(
            "optikin_check", plugin, {"x": x, "f": x * x, "g": x}, PLUGIN_OPTIONS[plugin](LimitsSpec(), settings)
        )
    except SettingError as exc:
        loc: tuple[str, ...] = (exc.name,) if exc.name else ()
        error = PydanticCustomError("plugin_setting", "{message}", {"message": exc.message})
        raise ValidationError.from_exception_data(
            "settings", [InitErrorDetails(type=error, loc=loc, input=settings.get(exc.name, settings))]
        ) from None
    return settings


class IpoptOptions(Options):
    """Preset options of backend ``ipopt``."""

    settings: dict[str, Any] = Field(
        default_factory=dict, description="IPOPT options (e.g. mu_strategy, hessian_approximation), over optikin's"
    )

    @field_validator("settings")
    @classmethod
    def _accepted_by_ipopt(cls, settings: dict[str, Any]) -> dict[str, Any]:
        return checked_settings("ipopt", settings)


class SqpmethodOptions(Options):
    """Preset options of backend ``sqpmethod``."""

    settings: dict[str, Any] = Field(
        default_factory=dict, description="sqpmethod options (e.g. qpsol, hessian_approximation), over optikin's"
    )

    @field_validator("settings")
    @classmethod
    def _accepted_by_sqpmethod(cls, settings: dict[str, Any]) -> dict[str, Any]:
        return checked_settings("sqpmethod", settings)


class NlpsolAdapter(NonlinearAdapter):
    """A CasADi ``nlpsol`` plugin (module docstring); subclasses set :attr:`plugin`."""

    plugin = ""
    options: IpoptOptions | SqpmethodOptions

    def plugin_options(self) -> dict[str, Any]:
        """The ``nlpsol`` options of this preset (limits and settings)."""
        return PLUGIN_OPTIONS[self.plugin](self.limits, self.options.settings)

    def _build(self, name: str, nlp: dict) -> ca.Function:
        try:
            return build_nlpsol(name, self.plugin, nlp, self.plugin_options())
        except SettingError as exc:
            raise SolverError(f"{self.preset.name}: {exc.message}") from None

    def solver(
        self, problem: LeastSquaresProblem
    ) -> tuple[BufferedFunction, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        key = ("nlpsol", self)
        if key not in problem.cache:
            nlp, lbx, ubx, lbg, ubg = nlp_of(problem)
            call = BufferedFunction(self._build(f"{problem.name}_{self.plugin}", nlp))
            problem.cache[key] = (call, lbx, ubx, lbg, ubg)
        return problem.cache[key]

    def solve_free(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        started = time.perf_counter()
        call, lbx, ubx, lbg, ubg = self.solver(problem)
        x0 = np.asarray(x0, dtype=float)
        reference = x0 if x_ref is None else np.asarray(x_ref, dtype=float)
        try:
            # nlpsol inputs: x0, p, lbx, ubx, lbg, ubg, lam_x0, lam_g0
            x = call(
                x0,
                np.concatenate([np.ravel(p), reference]),
                lbx,
                ubx,
                lbg,
                ubg,
                np.zeros(problem.n),
                np.zeros(len(lbg)),
            )[0].copy()
            # A preset may let IPOPT relax the bounds (bound_relax_factor); put the point back inside.
            x = np.where(problem.periodic, x, np.clip(x, problem.lower, problem.upper))
        except RuntimeError as exc:
            return self.finish(problem, x0, p, 0, started, error=f"{self.plugin}: {exc}")
        try:
            iterations = call.stats().get("iter_count", -1)
        except RuntimeError:  # some failures leave no statistics
            iterations = -1
        return self.finish(problem, x, p, iterations, started)


class Ipopt(NlpsolAdapter):
    """IPOPT through ``nlpsol`` (module docstring)."""

    plugin = "ipopt"


class Sqpmethod(NlpsolAdapter):
    """CasADi's ``sqpmethod`` through ``nlpsol`` (module docstring)."""

    plugin = "sqpmethod"

    def not_applicable(self, problem: LeastSquaresProblem, X: np.ndarray, P: np.ndarray) -> str | None:
        """An exact problem whose equality constraints ``r = 0`` have a rank-deficient Jacobian at every
        sample point: LICQ fails, and the SQP's QP subproblems are degenerate."""
        if not problem.exact or problem.m > problem.reduced.n:
            return None
        rank = problem.jacobian_rank(X, P)
        if rank >= problem.m:
            return None
        return (
            f"the {problem.m} equality constraints r = 0 have a rank-{rank} Jacobian at all {len(X)} "
            "sampled points: LICQ fails for this formulation"
        )


register_backend("ipopt", "nonlinear", "interior point (IPOPT) through CasADi nlpsol", options=IpoptOptions)(Ipopt)
register_backend("sqpmethod", "nonlinear", "CasADi's SQP method (qrqp QPs) through nlpsol", options=SqpmethodOptions)(
    Sqpmethod
)
