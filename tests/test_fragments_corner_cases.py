"""The corner-case examples really are the rows of DEFAULTS-CORNER-CASES.md on the installed MuJoCo, and every
row that applies to it is covered."""

from __future__ import annotations

import pytest

from conformance.fragments import CORNER_CASES, write
from conformance.fragments.corner_cases import NEW_SHORTCUTS, documented
from conformance.fragments.fuzz import corner_examples
from conformance.fragments.properties import compile_with_mujoco

ROWS = [str(i) for i in range(1, 30)] + ["17b"] + [f"A{i}" for i in range(1, 14)]


@pytest.mark.parametrize("case", CORNER_CASES, ids=[c.row for c in CORNER_CASES])
def test_mujoco_behaves_as_the_row_documents(case, tmp_path):
    model, error = compile_with_mujoco(write(case.document, tmp_path))
    documented(case, model, error)


def test_every_row_is_covered():
    covered = {case.row if case.row in ROWS else case.row[:-1] for case in CORNER_CASES}  # 12a, 12b -> 12
    assert covered == set(ROWS), set(ROWS) ^ covered


def test_examples_feed_both_properties():
    accepted, rejected = corner_examples(error=False), corner_examples(error=True)
    assert len(accepted) + len(rejected) == len(CORNER_CASES)
    rejected_rows = {case.row for case in CORNER_CASES if case.expect is None}
    expected = {"2", "12a", "12b", "14a", "14b", "15", "16a", "16b", "17b"} | ({"A13"} if NEW_SHORTCUTS else set())
    assert rejected_rows == expected
