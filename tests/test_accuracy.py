"""The accuracy study's pipeline, on a tiny configuration (the real study takes minutes)."""

from __future__ import annotations

import pytest
from rustcloth import INTEGRATORS, accuracy

pytest.importorskip("matplotlib")  # the study extra; skipped against a core-only install
Image = pytest.importorskip("PIL.Image")


def test_quick_study_writes_tables_and_a_plot(tmp_path):
    assert accuracy.main(["--quick", "--out", str(tmp_path)]) == 0
    report = (tmp_path / "accuracy.md").read_text()
    assert "## Largest stable dt" in report and "## Reading" in report
    for integrator in INTEGRATORS:
        assert f"| {integrator} | 1/240 |" in report
    with Image.open(tmp_path / "accuracy.png") as image:
        assert image.size[0] > 400 and image.size[1] > 300


def test_pareto_front_keeps_only_unbeaten_runs():
    runs = [accuracy.Run("c", "a", 1.0, True), accuracy.Run("c", "b", 1.0, True),
            accuracy.Run("c", "c", 1.0, True)]
    points = [(1.0, 1e-2, runs[0]), (2.0, 1e-1, runs[1]), (3.0, 1e-3, runs[2])]
    assert accuracy.pareto(points) == [runs[0], runs[2]]
