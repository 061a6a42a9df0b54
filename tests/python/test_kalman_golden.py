"""Checks the stored Kalman golden CSVs against filterpy (tools/golden/kalman_golden.py).

Run from the repository root:  python -m pytest tests/python/test_kalman_golden.py
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(REPO_ROOT / "tools" / "golden"))

kg = importlib.import_module("kalman_golden")

DATA_DIR = REPO_ROOT / "crates" / "kflex-estimate" / "tests" / "data"
CASES = kg.cases()


def test_case_list() -> None:
    assert [c.name for c in CASES] == ["paper_as_run", "loose_as_run", "paper_as_written"]
    assert kg.DEFAULT_OUT.resolve() == DATA_DIR.resolve()


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_stored_csv_is_what_filterpy_computes(case) -> None:
    stored = kg.read_case(kg.csv_path(DATA_DIR, case))
    fresh = kg.run(case)
    assert stored.shape == fresh.shape
    np.testing.assert_allclose(stored, fresh, rtol=kg.CHECK_RTOL, atol=kg.CHECK_ATOL, equal_nan=True)


def test_as_written_holds_between_steps() -> None:
    case = next(c for c in CASES if c.every > 1)
    data = kg.run(case)
    # ticks that do not step leave the state as it was
    for i in range(1, len(data)):
        if (i + 1) % case.every != 0:
            np.testing.assert_array_equal(data[i, 3:], data[i - 1, 3:])


def test_missing_measurements_are_in_the_data() -> None:
    data = kg.run(CASES[0])
    assert np.isnan(data[:, 1]).any() and np.isnan(data[:, 2]).any()
