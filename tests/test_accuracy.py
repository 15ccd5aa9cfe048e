"""The accuracy study's pipeline, on a tiny configuration (the real study takes minutes), and
its pieces: the Pareto front, the fitted order, the float64 reference."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import rustcloth
from rustcloth import INTEGRATORS, accuracy
from rustcloth.reference import ReferenceCloth
from rustcloth.study import accuracy as study


def test_quick_study_writes_tables_and_a_plot(tmp_path):
    pytest.importorskip("matplotlib")  # the study extra; the wheel's core-only run has none
    image_module = pytest.importorskip("PIL.Image")
    assert accuracy.main(["--quick", "--out", str(tmp_path)]) == 0
    report = (tmp_path / "accuracy.md").read_text()
    for section in ("## Measured orders", "## Largest stable dt", "## Stiff cloth at 1/60 s",
                    "## Reading"):
        assert section in report
    for integrator in INTEGRATORS:
        assert f"| {integrator} | 1/240 |" in report
    with image_module.open(tmp_path / "accuracy.png") as image:
        assert image.size[0] > 400 and image.size[1] > 300


def test_without_matplotlib_the_study_names_the_extra_and_exits_2(monkeypatch, capsys,
                                                                   tmp_path):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    assert accuracy.main(["--quick", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "rustcloth[study]" in err and len(err.splitlines()) == 1


def test_the_study_writes_under_out_unless_told(monkeypatch, tmp_path):
    # Without --out the report goes under ./out, never into the docs of whatever checkout the
    # user stands in.
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # stop before the study itself
    assert accuracy.main(["--quick"]) == 2
    assert (tmp_path / "out" / "accuracy").is_dir() and not (tmp_path / "docs").exists()


def test_an_unusable_out_folder_is_one_line_before_the_study(capsys):
    # A folder that cannot be made is a one-line error before minutes of study, not a
    # traceback after them.
    assert accuracy.main(["--quick", "--out", "/dev/full/x"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rustcloth accuracy: error: Not a directory: '/dev/full/x'")
    assert err.count("\n") == 1


def test_pareto_front_keeps_only_unbeaten_runs():
    runs = [accuracy.Run("c", "a", 1.0, True), accuracy.Run("c", "b", 1.0, True),
            accuracy.Run("c", "c", 1.0, True)]
    points = [(1.0, 1e-2, runs[0]), (2.0, 1e-1, runs[1]), (3.0, 1e-3, runs[2])]
    assert accuracy.pareto(points) == [runs[0], runs[2]]


def test_the_measured_order_ignores_points_at_the_floor():
    runs = [study.Run("c", "x", dt, True, error=err)
            for dt, err in [(0.1, 1e-2), (0.05, 2.5e-3), (0.025, 6.25e-4), (0.0125, 2e-6),
                            (0.00625, 5e-6)]]
    # The finest two above three times the floor before the error stops falling: 0.05 and
    # 0.025, second order (0.0125 is at the floor, and round-off grows again at 0.00625).
    assert math.isclose(study.slope(runs, floor=1e-6), 2.0, rel_tol=1e-9)
    assert math.isnan(study.slope(runs[:1], floor=1e-6))


def test_the_float64_reference_falls_freely_and_swings_like_the_solver():
    # No springs engaged: a free cloth falls as x0 + g t^2 / 2 to the reference's tolerance.
    case = study.Case("stretched", False, 6, 0.1)
    scene = case.scene("rk4", 1e-3).replace(gravity=[0.0, -9.81, 0.0])
    sim = rustcloth.Simulation(scene)
    cloth = ReferenceCloth(scene.to_dict(), positions=sim.positions, velocities=sim.velocities,
                           masses=sim.masses)
    cloth.integrate(0.3)
    expected = sim.positions.astype(float) + np.array([0.0, -9.81 * 0.09 / 2, 0.0])
    np.testing.assert_allclose(cloth.positions, expected, atol=1e-9)
    # With springs: RK4 in float32 at a fine step lands within round-off of it.
    hanging = study.Case("hanging", True, 8, 0.1)
    ref = study.reference(hanging.scene("rk4", 1e-4), 0.1)
    sim, _ = study.simulate(hanging.scene("rk4", 1e-4), 0.1)
    assert study.rms(sim.positions, ref) < 1e-5


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_the_orders_show_as_slopes_above_the_floor(integrator):
    case = study.Case("stretched", False, 8, 0.1)
    ref = study.reference(case.scene("rk4", 1e-4), case.time, case.start)
    # Steps from near each method's stability limit down, where the truncation error stands
    # far above float32's round-off.
    # (Whole numbers of steps to the case's time: a ladder that missed it by a fraction of a
    # step would measure that fraction, not the truncation error.)
    limit = case.scene(integrator, 1e-3).stability_report(warn=False).stable_dt[integrator]
    steps = math.ceil(1.5 * case.time / limit)
    ladder = [case.time / (steps * k) for k in (1, 2, 4, 8)]
    runs = [study.measure(study.Run(case.label, integrator, dt, False),
                          case.scene(integrator, dt), case.time, ref, case.start)
            for dt in ladder]
    order = study.slope(runs, floor=1e-7)
    expected = {"symplectic_euler": 1.0, "rk4": 4.0}[integrator]
    assert abs(order - expected) < 0.35, (integrator, order, [r.error for r in runs])
