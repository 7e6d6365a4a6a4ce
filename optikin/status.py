"""The statuses optikin writes: one :class:`Status` per outcome, a ``str`` so results read and compare as text.

Each member equals its text (``Status.OK == "ok"``) and prints as it (``f"{Status.OK}"`` is ``ok``), so a
``result.json``, an ``arrays.npz`` status array or a message is the same whether a status came from a
:class:`Status` or from the text in a file.
"""

from __future__ import annotations

import sys
from enum import Enum

if sys.version_info >= (3, 11):
    from enum import StrEnum
else:

    class StrEnum(str, Enum):
        """:class:`enum.StrEnum` of Python 3.11: members are their text, and print as it."""

        __str__ = str.__str__
        __format__ = str.__format__


__all__ = ["SAMPLE_STATUSES", "SOLVED", "Status"]


class Status(StrEnum):
    """An outcome optikin reports.

    ``ok`` solved exactly, to the tolerance; ``fit`` a least-squares minimum whose residual lies within the
    stated measurement noise; ``unreachable`` a minimum beyond it (the closest reachable configuration);
    ``not_converged`` out of iterations; ``timeout`` out of time; ``failed`` no usable answer (non-finite,
    outside the bounds, the solver gave up); ``not_identifiable`` a calibration whose parameters the data
    cannot tell apart (a calibration's verdict, not a sample's status).

    Its ``repr`` is the text's too (``'ok'``), so a message or a printed tuple reads as before.
    """

    OK = "ok"
    FIT = "fit"
    UNREACHABLE = "unreachable"
    FAILED = "failed"
    NOT_CONVERGED = "not_converged"
    TIMEOUT = "timeout"
    NOT_IDENTIFIABLE = "not_identifiable"

    def __repr__(self) -> str:
        return repr(self.value)


SAMPLE_STATUSES = (
    Status.OK,
    Status.FIT,
    Status.UNREACHABLE,
    Status.FAILED,
    Status.NOT_CONVERGED,
    Status.TIMEOUT,
)
"""The statuses a sample of a result may have (in the order ``status_counts`` lists them)."""
SOLVED = (Status.OK, Status.FIT)
"""The sample statuses that count as solved."""
