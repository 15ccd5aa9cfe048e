"""examples/fit_drape.py keeps working: its quick grid runs, finds a fit and draws the plot."""

from __future__ import annotations

import os
import sys

import pytest

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")


@pytest.fixture
def fit_drape(monkeypatch):
    if not os.path.isfile(os.path.join(EXAMPLES, "fit_drape.py")):
        # The wheel's test run (scripts/test-wheel.sh) copies tests/ alone, without examples/.
        pytest.skip("examples/ is not beside this copy of the tests")
    monkeypatch.syspath_prepend(EXAMPLES)
    import fit_drape

    yield fit_drape
    sys.modules.pop("fit_drape", None)


def test_the_silhouette_of_the_target_covers_the_sphere(fit_drape):
    masks = fit_drape.target_silhouettes()
    assert masks.shape == (9, fit_drape.RES, fit_drape.RES) and masks.dtype == bool
    assert masks[-1].sum() > 0.1 * masks[-1].size  # a draped cloth, seen from the front


def test_the_quick_fit_runs_and_plots(fit_drape, tmp_path, capsys):
    plot = tmp_path / "surface.png"
    assert fit_drape.main(["--quick", "--out", str(tmp_path / "out"), "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "15 runs (15 ran now)" in out and "best:   k_bend = " in out
    assert plot.stat().st_size > 10_000
