"""``optikin export --what qp-step``: the C step (dual active set in C) against daqp and the Python controller.

The reference QP solver is daqp (a third-party dual active-set solver, at a tight primal tolerance),
called on ``H``, ``g`` of :func:`optikin.control.task.task_step_function` and the box of
:class:`optikin.control.limits.RateBounds` evaluated in Python; the C command must agree to 1e-9,
with the same status where daqp finds the QP infeasible (the controller's fallback then). The
steps of a problem without rows are also compared with :meth:`QPController.command` using the
``qp-daqp`` preset.
"""

from __future__ import annotations

import shutil
import subprocess

import casadi as ca
import numpy as np
import pytest

from optikin.export import Export, build, export
from optikin.export.qp_step import QPExportSetup, qp_setup

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")

daqp = pytest.importorskip("daqp")

STATUS = {0: "ok", 1: "infeasible", 2: "not_converged", 3: "invalid_input", 4: "failed"}


def run(exported: Export, lines: list[str]) -> np.ndarray:
    """The example of ``exported`` (built once) on ``lines``; its printed rows as an array."""
    executable = exported.folder / "example"
    if not executable.exists():
        build(exported)
    data = exported.folder / "steps.txt"
    data.write_text("\n".join(lines) + "\n")
    out = subprocess.run([str(executable), str(data)], capture_output=True, text=True, timeout=60, check=True)
    assert "per_call_us" in out.stderr
    return np.array([[float(v) for v in line.split()] for line in out.stdout.splitlines()])


def line(step: np.ndarray, A: np.ndarray | None = None, b: np.ndarray | None = None) -> str:
    rows = [] if A is None else [f"{' '.join(repr(float(v)) for v in a)} {float(c)!r}" for a, c in zip(A, b)]
    return " ".join(repr(float(v)) for v in step) + f" {len(rows)} " + " ".join(rows)


class Reference:
    """The QP of a step in Python (CasADi's VM for H, g; RateBounds for the box) solved by daqp."""

    def __init__(self, setup: QPExportSetup):
        from optikin.control.task import task_step_function

        self.setup, self.n = setup, setup.arm.n_config
        self.f = task_step_function(setup.arm, setup.task)

    def __call__(self, step: np.ndarray, A: np.ndarray | None = None, b: np.ndarray | None = None):
        s, n = self.setup, self.n
        m = (len(step) - n) // 3
        q, x, x_ref, xdot_ref = step[:n], step[n : n + m], step[n + m : n + 2 * m], step[n + 2 * m :]
        H, g = (np.asarray(v) for v in self.f(q, x, x_ref, xdot_ref, s.gain, s.damping)[3::2])
        s.bounds.update(q)
        lb, ub = s.bounds.lb.copy(), s.bounds.ub.copy()
        A = np.zeros((0, n)) if A is None else A
        b = np.zeros(0) if b is None else b
        upper = np.concatenate([ub, np.full(len(b), 1e30)])
        lower = np.concatenate([lb, np.maximum(b, -1e30)])
        sol, _, exitflag, _ = daqp.solve(
            H, g.ravel(), A, upper, lower, np.zeros(n + len(b), dtype=np.intc), primal_tol=1e-12
        )
        if exitflag == 1:
            return "ok", np.clip(sol, lb, ub)
        status = "infeasible" if exitflag == -1 else f"daqp {exitflag}"
        return status, np.clip(np.zeros(n), lb, ub)


@pytest.fixture(scope="module")
def nominal(tmp_path_factory):
    setup = qp_setup("track-nominal")
    exported = export("track-nominal", "qp-step", tmp_path_factory.mktemp("qp"))
    return setup, exported


def random_steps(setup: QPExportSetup, count: int, seed: int, spread: float = 1.0) -> np.ndarray:
    """Configurations drawn over (and ``spread`` times beyond) the limits, references from nearby ones."""
    arm, rng = setup.arm, np.random.default_rng(seed)
    from optikin.control.task import TASK_FUNCTIONS

    q_symbol = ca.SX.sym("q", arm.n_config)  # a plain Function: the configurations go beyond the limits
    fk = ca.Function("fk", [q_symbol], [arm.function(TASK_FUNCTIONS[setup.task][0])(q_symbol)])
    middle, half = 0.5 * (arm.upper + arm.lower), 0.5 * (arm.upper - arm.lower)
    rows = []
    for _ in range(count):
        q = middle + spread * half * rng.uniform(-1, 1, arm.n_config)
        target = q + 0.2 * half * rng.normal(size=arm.n_config)
        x, x_ref = (np.asarray(fk(v)).ravel() for v in (q, target))
        rows.append(np.concatenate([q, x, x_ref, rng.normal(scale=0.05, size=len(x))]))
    return np.array(rows)


def compare(out: np.ndarray, expected) -> None:
    assert [STATUS[int(s)] for s in out[:, 0]] == [s for s, _ in expected]
    np.testing.assert_allclose(out[:, 2:], [x for _, x in expected], rtol=0, atol=1e-9)


def test_steps_along_the_reference_agree_with_the_controller(nominal):
    """The problem's own steps: the exported command is QPController.command with the qp-daqp preset."""
    from optikin.control.qp import QPController
    from optikin.export.context import registered_preset

    import optikin.solvers.qp.qp_qpsolvers  # noqa: F401  (registers qp_qpsolvers)

    setup, exported = nominal
    n = setup.arm.n_config
    solver = registered_preset("qp-daqp").build().create(n, (setup.steps.shape[1] - n) // 3)
    controller = QPController(
        setup.arm,
        setup.dt,
        setup.task,
        setup.gain,
        setup.damping,
        solver=solver,
        rate_limits=setup.rate_limits,
        margin=setup.margin,
        limit_gain=setup.limit_gain,
        fallback=setup.fallback,
    )
    out = run(exported, [line(s) for s in setup.steps])
    m = (setup.steps.shape[1] - n) // 3
    for row, s in zip(out, setup.steps):
        command = controller.command(s[:n], s[n : n + m], s[n + m : n + 2 * m], s[n + 2 * m :])
        assert controller.status == "ok" and row[0] == 0
        np.testing.assert_allclose(row[2:], command, rtol=0, atol=1e-9)


def test_active_bounds_agree_with_daqp(nominal):
    """Configurations up to 1.3 x beyond the limits and large errors: many steps have active bounds."""
    setup, exported = nominal
    steps = random_steps(setup, 150, seed=5, spread=1.3)
    out = run(exported, [line(s) for s in steps])
    reference = Reference(setup)
    compare(out, [reference(s) for s in steps])
    assert (out[:, 1] > 0).mean() > 0.3  # active constraints on many steps


def test_rows_and_an_infeasible_qp_agree_with_daqp(nominal):
    """Random rows A qdot >= b (some inactive, b = -inf), and rows that contradict the box: infeasible in both,
    the hold fallback (qdot = 0 in the box) commanded."""
    setup, exported = nominal
    n = setup.arm.n_config
    rng = np.random.default_rng(11)
    steps = random_steps(setup, 40, seed=6)
    cases = []
    for k, s in enumerate(steps):
        A = rng.normal(size=(3, n))
        b = rng.normal(scale=0.3, size=3)
        if k % 4 == 0:
            b[1] = -np.inf
        if k % 5 == 0:  # qdot_0 >= its rate limit + 1: outside the box
            A[0] = np.eye(n)[0]
            b[0] = setup.bounds.rate[0] + 1.0
        cases.append((s, A, b))
    out = run(exported, [line(*c) for c in cases])
    reference = Reference(setup)
    expected = [reference(*c) for c in cases]
    compare(out, expected)
    statuses = [s for s, _ in expected]
    assert statuses.count("infeasible") >= 8 and statuses.count("ok") >= 20


def test_invalid_input_is_a_status(nominal):
    setup, exported = nominal
    step = setup.steps[0].copy()
    step[0] = np.nan
    out = run(exported, [line(setup.steps[0]), line(step), line(setup.steps[1], np.ones((1, 6)), np.array([np.nan]))])
    assert [STATUS[int(s)] for s in out[:, 0]] == ["ok", "invalid_input", "invalid_input"]
    assert (out[1:, 2:] == 0).all()


@pytest.mark.slow
def test_eight_sections_agree_with_daqp(tmp_path):
    """24 rates: the largest size the issue names."""
    sections = 8
    overrides = [
        ("arm.params.section_lengths", [0.18] * sections),
        ("data.params.waypoints", [[0.18, 0.6, 0.3] * sections, [0.17, 1.0, 0.8] * sections]),
        ("options.start_offset", [0.003, 0.05, -0.05] * sections),
    ]
    setup = qp_setup("track-nominal", overrides)
    exported = export("track-nominal", "qp-step", tmp_path, overrides=overrides)
    steps = random_steps(setup, 40, seed=7, spread=1.2)
    out = run(exported, [line(s) for s in steps])
    reference = Reference(setup)
    compare(out, [reference(s) for s in steps])
