"""Shared by the examples: RUSTCLOTH_EXAMPLE_QUICK=1 (set by tests/test_examples.py) makes each
one run in a few seconds on a smaller cloth and a shorter time; the answers are coarser."""

from __future__ import annotations

import os

QUICK = os.environ.get("RUSTCLOTH_EXAMPLE_QUICK", "") not in ("", "0")


def pick(full: float, quick: float) -> float:
    """``full`` for a real run, ``quick`` in the tests."""
    return quick if QUICK else full


def size(full: int, quick: int) -> int:
    """A grid size: ``full`` for a real run, ``quick`` in the tests."""
    return quick if QUICK else full
