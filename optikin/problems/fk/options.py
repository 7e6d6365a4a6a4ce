"""Options of the ``fk`` kind: none yet, so any field under ``options:`` is an error naming it."""

from __future__ import annotations

from optikin.options import Options


class FkOptions(Options):
    """``options:`` of kind ``fk``: takes none."""
