"""A user's script that touches the whole public API, checked by `mypy --strict tests/typecheck`
(`make lint`) and run by tests/test_typing.py: a signature that loses its types (an `Any`
return, a literal that leaves a value out) fails the first, a wrong annotation the second."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import numpy.typing as npt
import rustcloth
from rustcloth import export
from rustcloth.drivers import TwistDriver
from rustcloth.settings import ClothSettings, IntegratorName
from rustcloth.sweep import Record, Sweep, SweepResult


def small(nx: int = 8) -> rustcloth.Scene:
    scene = rustcloth.load_scene("hanging").replace(cloth={"nx": nx, "ny": nx})
    cloth: ClothSettings = scene.cloth
    assert cloth["nx"] == nx and cloth["plane"] in ("xz", "xy")
    assert scene.dt > 0 and scene.floor is None and scene.watchdog["max_substeps"] >= 1
    return scene


def every_integrator(scene: rustcloth.Scene) -> dict[IntegratorName, float]:
    energies: dict[IntegratorName, float] = {}
    for name in rustcloth.INTEGRATORS:
        sim = rustcloth.Simulation(scene)
        sim.integrator = name
        sim.step(5)
        energies[name] = sim.energy().total
    sim.integrator = "projective_dynamics"
    return energies


def interact(sim: rustcloth.Simulation) -> int:
    hit = sim.pick([0.0, 1.0, 3.0], [0.0, 0.0, -1.0])
    if hit is not None:
        index, _distance = hit
        sim.grab(index)
        sim.drag_to([0.0, 1.2, 0.5])
        sim.step(10)
        sim.release()
    sim.pin(0, target=[0.0, 1.0, 0.0])
    severed: int = sim.sever_stroke([([-1.0, 1.0, 3.0], [0.0, 0.0, -1.0]),
                                     ([1.0, 1.0, 3.0], [0.0, 0.0, -1.0])])
    return severed + sim.pieces()


def arrays(sim: rustcloth.Simulation) -> float:
    x: npt.NDArray[np.float32] = sim.positions
    mesh: export.Mesh = sim.to_mesh()
    tri: npt.NDArray[np.uint32] = mesh.triangles
    report: rustcloth.StabilityReport = sim.scene.stability_report()
    profile: rustcloth.Profile = sim.profile()
    limit = report.stable_dt[sim.integrator] or 0.0
    return float(x.sum()) + len(tri) + limit + len(profile.passes)


def files(sim: rustcloth.Simulation, out: Path) -> list[Path]:
    written: list[Path] = []
    try:
        written.append(sim.export(out / "frame.obj"))
        with export.recorder(out / "run_##.obj", fps=30.0) as rec:
            rec.add(sim)
    except ImportError as err:  # the export extra is not installed: the error names it
        print(f"skipped the files: {err}", file=sys.stderr)
    return written


def sweep_of(scene: rustcloth.Scene, out: Path) -> SweepResult:
    from rustcloth.sweep import run_sweep

    sweep = Sweep(base=scene, grid={"cloth.k_bend": [1.0, 5.0]}, steps=20,
                  record=Record(every=10))
    return run_sweep(sweep, out, "local", workers=1)


def main() -> None:
    scene = small()
    every_integrator(scene)
    sim = rustcloth.Simulation(scene)
    driver = TwistDriver(sim, turns=0.5, seconds=0.05)
    for _ in range(5):
        driver.before_step(sim)
        sim.step()
    sim.advance(0.05)
    interact(sim)
    arrays(sim)
    with tempfile.TemporaryDirectory() as tmp:
        files(sim, Path(tmp))
        result = sweep_of(scene, Path(tmp) / "sweep")
        for record in result.ok():
            positions = result.load(record)["positions"]
            assert np.isfinite(positions).all() and (abs(positions) < 100).all()
    try:
        sim.pin(10**6)
    except rustcloth.ParticleIndexError as err:
        assert isinstance(err, IndexError)


if __name__ == "__main__":
    main()
