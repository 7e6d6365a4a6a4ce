"""optikin.status: every status is its text wherever a result holds it (JSON, numpy arrays, messages)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optikin.results import STATUSES, Result
from optikin.status import SAMPLE_STATUSES, SOLVED, Status


def test_a_status_is_its_text_in_json_arrays_and_messages():
    assert json.dumps({Status.NOT_CONVERGED: [Status.OK]}) == '{"not_converged": ["ok"]}'
    array = np.array([Status.OK, Status.UNREACHABLE])
    assert array.dtype == np.dtype("<U11") and array.tobytes() == np.array(["ok", "unreachable"]).tobytes()
    assert f"{Status.TIMEOUT}" == str(Status.TIMEOUT) == "timeout" and f"{Status.FIT:>4}" == " fit"
    assert Status("failed") is Status.FAILED and {"ok": 1}[Status.OK] == 1
    assert repr((Status.OK, [Status.FIT])) == "('ok', ['fit'])"


def test_the_sample_statuses_are_the_results_ones_and_the_verdict_is_not_among_them():
    assert STATUSES == SAMPLE_STATUSES == ("ok", "fit", "unreachable", "failed", "not_converged", "timeout")
    assert SOLVED == ("ok", "fit") and Status.NOT_IDENTIFIABLE not in SAMPLE_STATUSES
    assert set(Status) == {*SAMPLE_STATUSES, Status.NOT_IDENTIFIABLE}


def test_a_result_counts_statuses_written_as_text_and_as_members_alike():
    result = Result("p", "fk", None, "t", {}, ["ok", Status.OK, "failed"])
    assert result.status_counts() == {"ok": 2, "failed": 1} and not result.succeeded
    assert json.dumps(result.summary()["status_counts"]) == '{"ok": 2, "failed": 1}'
    with pytest.raises(ValueError, match=r"unknown sample status \['done'\]; allowed: \('ok', 'fit', "):
        Result("p", "fk", None, "t", {}, ["done"])
