"""Studies beyond one run: ``optikin sweep FILE`` solves a problem over axes of overrides.

A sweep file (:mod:`optikin.sweep.spec`) names a base problem, axes of dotted-field overrides combined
as a product or zipped, and the metrics to collect. Each cell is one :func:`optikin.runner.solve` in a
worker process (:mod:`optikin.sweep.cell`), run by joblib's loky backend or on a Dask cluster
(:mod:`optikin.sweep.run`); every finished cell is written atomically as it completes, keyed by a hash
of its problem, overrides, preset and optikin version, so a rerun does only the missing or changed
cells; the merged table and the figures are written at the end (:mod:`optikin.sweep.store`).

The same engines split one large problem's samples (``optikin solve NAME --jobs N`` / ``--dask``):
:mod:`optikin.sweep.chunks`.
"""

from optikin.sweep.run import SweepReport, run_sweep
from optikin.sweep.spec import Cell, SweepSpec, expand, load_sweep, parse_range

__all__ = ["Cell", "SweepReport", "SweepSpec", "expand", "load_sweep", "parse_range", "run_sweep"]
