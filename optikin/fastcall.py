"""Calling a small CasADi Function from Python without the overhead of ``f(x)``.

``f(q)`` converts its arguments to ``DM`` and its results back, which for a small
Function costs far more than the arithmetic; ``Function.buffer()`` evaluates in
place on numpy arrays allocated once, with CasADi's SX virtual machine or, faster
still, code-generated and compiled. Outputs are densified first, so every array
holds all entries of its matrix in column-major order.

Two ways to call, same arrays: write the inputs in place and call with no
arguments (control loops, :mod:`optikin.control`, :mod:`optikin.curves`), or pass
the arguments, which are copied in (the solvers of :mod:`optikin.solvers`).
Either way the outputs returned are the preallocated arrays themselves,
overwritten by the next call: copy what you keep.
"""

from __future__ import annotations

from typing import Any, cast

import casadi as ca
import numpy as np

from optikin.interrupt import calls_casadi


class BufferedFunction:
    """A CasADi Function bound to preallocated numpy arrays.

    Write the inputs into :attr:`inputs` (in place) or pass them to the call, call the
    object, read :attr:`outputs` (also returned by the call).

    Parameters
    ----------
    function:
        Any CasADi Function (including solvers: ``nlpsol``, ``rootfinder``); its outputs
        are densified.
    compiled:
        Generate C code, compile it with gcc and call the compiled library
        (built once, cached on disk by content) instead of the SX virtual machine.
    """

    def __init__(self, function: ca.Function, compiled: bool = False):
        dense = _densified(function)
        if compiled:
            from optikin.codegen import compile_function

            dense = compile_function(dense)
        self.function = dense
        self.inputs = [np.zeros(dense.nnz_in(i)) for i in range(dense.n_in())]
        self.outputs = [np.zeros(dense.nnz_out(i)) for i in range(dense.n_out())]
        buffer, self._trigger = dense.buffer()
        # Any: CasADi's stub asks for a byte count that its Python binding does not take.
        self._buffer: Any = cast(Any, buffer)
        for i, array in enumerate(self.inputs):
            self._buffer.set_arg(i, array.data)
        for i, array in enumerate(self.outputs):
            self._buffer.set_res(i, array.data)

    @calls_casadi
    def __call__(self, *args: Any) -> list[np.ndarray]:
        """Evaluate; arguments given (the first ones, in order) are copied into :attr:`inputs` first.

        An argument is flattened in column-major order, as CasADi stores matrices; inputs not
        given keep their contents. Returns :attr:`outputs`.
        """
        if len(args) > len(self.inputs):
            raise TypeError(f"{self.function.name()}: {len(args)} arguments for {len(self.inputs)} inputs")
        for slot, value in zip(self.inputs, args):
            slot[:] = np.ravel(value, order="F")
        self._trigger()
        return self.outputs

    def stats(self) -> dict[str, Any]:
        """The Function's statistics of the last call (e.g. ``iter_count`` of a solver)."""
        return self._buffer.stats()

    def output_matrix(self, i: int) -> np.ndarray:
        """Output ``i`` as a ``rows x cols`` view (no copy) of its column-major buffer."""
        rows, cols = self.function.size_out(i)
        return self.outputs[i].reshape(cols, rows).T


def _densified(f: ca.Function) -> ca.Function:
    """``f`` with every output dense (structural zeros stored), so buffers have fixed layouts.

    An SX Function is wrapped with SX symbols, anything else (a solver, an external) with MX.
    """
    if all(f.sparsity_out(i).is_dense() for i in range(f.n_out())):
        return f
    symbol: Any = ca.SX if f.is_a("SXFunction") else ca.MX
    args = [symbol.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    outs = [ca.densify(o) for o in f.call(args)]
    return ca.Function(f"{f.name()}_dense", args, outs, f.name_in(), f.name_out())
