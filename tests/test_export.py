"""Mesh export: the arrays of to_mesh, and every file format read back by a second library
(trimesh for OBJ, PLY and glTF binary; pxr for USD) and compared with the simulation."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest
import rustcloth
from conftest import small_scene
from rustcloth import export
from rustcloth._extras import MissingExtra


@pytest.fixture
def trimesh():
    return pytest.importorskip("trimesh")


@pytest.fixture
def pxr():
    return pytest.importorskip("pxr")


def moved_and_cut() -> rustcloth.Simulation:
    """The 8 x 6 test cloth after 50 steps, with two particles cut out of its middle."""
    sim = rustcloth.Simulation(small_scene())
    sim.step(50)
    sim.cut(3 * 8 + 3)
    sim.cut(3 * 8 + 4)
    return sim


def obj_records(path, tag: str) -> np.ndarray:
    """The numbers of every line of ``path`` starting with ``tag`` (``v``, ``vn``, ``vt``)."""
    return np.array([line.split()[1:] for line in path.read_text().splitlines()
                     if line.split()[:1] == [tag]], dtype=float)


def test_to_mesh_is_the_simulation_state_with_grid_uvs():
    sim = moved_and_cut()
    mesh = sim.to_mesh()
    assert mesh.vertices.dtype == np.float32 and mesh.vertices.shape == (48, 3)
    assert mesh.normals.dtype == np.float32 and mesh.normals.shape == (48, 3)
    assert mesh.triangles.dtype == np.uint32 and mesh.uvs.dtype == np.float32
    assert np.array_equal(mesh.vertices, sim.positions)
    assert np.array_equal(mesh.normals, sim.normals)
    assert np.array_equal(mesh.triangles, sim.triangles)
    for j in range(sim.ny):
        for i in range(sim.nx):
            assert tuple(mesh.uvs[j * sim.nx + i]) == pytest.approx((i / 7, j / 5), abs=1e-7)


def test_to_mesh_keeps_only_live_triangles():
    sim = rustcloth.Simulation(small_scene())
    full = len(sim.to_mesh().triangles)
    assert full == 2 * 7 * 5
    sim.cut(27)
    mesh = sim.to_mesh()
    assert 27 not in mesh.triangles
    assert len(mesh.triangles) == full - 6  # an inner particle belongs to six triangles
    assert sim.alive[mesh.triangles].all()


def test_triangles_wind_counter_clockwise_around_the_normals():
    # USD's rightHanded orientation and glTF both take counter-clockwise faces as the front.
    sim = rustcloth.Simulation("drape")
    sim.step(200)
    m = sim.to_mesh()
    v, t = m.vertices.astype(np.float64), m.triangles.astype(np.int64)
    face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert (np.einsum("ij,ij->i", face, m.normals[t].sum(axis=1)) > 0).all()


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb"])
def test_exported_frame_reads_back_with_trimesh(tmp_path, trimesh, suffix):
    sim = moved_and_cut()
    mesh = sim.to_mesh()
    path = sim.export(tmp_path / f"cloth{suffix}")
    assert path.exists() and path.stat().st_size > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # trimesh on the unused vertices
        loaded = trimesh.load(path, force="mesh", process=False)
    # Each triangle's corners, positions and UVs, as the simulation has them. OBJ keeps 8
    # significant digits; PLY and glTF store float32 exactly.
    tol = 1e-6 if suffix == ".obj" else 0.0
    assert loaded.faces.shape == mesh.triangles.shape
    np.testing.assert_allclose(loaded.vertices[loaded.faces], mesh.vertices[mesh.triangles],
                               rtol=0, atol=tol)
    np.testing.assert_allclose(loaded.visual.uv[loaded.faces], mesh.uvs[mesh.triangles],
                               rtol=0, atol=1e-6)


def test_obj_file_has_every_particle_with_its_normal_and_uv(tmp_path, trimesh):
    # Vertex p of the file is particle p, cut ones included, so indices match the simulation.
    sim = moved_and_cut()
    mesh = sim.to_mesh()
    path = sim.export(tmp_path / "cloth.obj")
    np.testing.assert_allclose(obj_records(path, "v"), mesh.vertices, rtol=0, atol=1e-6)
    np.testing.assert_allclose(obj_records(path, "vn"), mesh.normals, rtol=0, atol=1e-6)
    np.testing.assert_allclose(obj_records(path, "vt"), mesh.uvs, rtol=0, atol=1e-6)
    faces = [line.split()[1:] for line in path.read_text().splitlines() if line[:2] == "f "]
    corners = np.array([[c.split("/")[0] for c in f] for f in faces], dtype=np.int64) - 1
    assert np.array_equal(corners, mesh.triangles)
    assert "mtllib" not in path.read_text() and "usemtl" not in path.read_text()


def test_ply_and_glb_store_the_simulation_normals(tmp_path, trimesh):
    from trimesh.exchange.gltf import load_glb

    sim = moved_and_cut()
    mesh = sim.to_mesh()
    ply = trimesh.load(sim.export(tmp_path / "cloth.ply"), process=False, fix_texture=False)
    raw = ply.metadata["_ply_raw"]["vertex"]["data"]
    normals = np.column_stack([raw["nx"], raw["ny"], raw["nz"]]).reshape(-1, 3)
    assert np.array_equal(normals, mesh.normals)
    with open(sim.export(tmp_path / "cloth.glb"), "rb") as f:
        (glb,) = load_glb(f)["geometry"].values()
    assert np.array_equal(glb["vertices"], mesh.vertices)
    assert np.array_equal(glb["faces"], mesh.triangles)
    np.testing.assert_allclose(glb["vertex_normals"], mesh.normals, rtol=0, atol=2e-7)


def test_export_refuses_an_unknown_suffix(tmp_path):
    sim = rustcloth.Simulation(small_scene())
    with pytest.raises(ValueError, match=r"cloth\.stl.*\.obj, \.ply, \.glb"):
        sim.export(tmp_path / "cloth.stl")
    assert not (tmp_path / "cloth.stl").exists()


def test_export_without_trimesh_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "trimesh", None)
    sim = rustcloth.Simulation(small_scene())
    with pytest.raises(MissingExtra, match=r"pip install 'rustcloth\[export\]'") as err:
        sim.export(tmp_path / "cloth.obj")
    assert isinstance(err.value, ImportError) and err.value.extra == "export"


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb"])
def test_export_without_pillow_names_the_export_extra(tmp_path, monkeypatch, trimesh, suffix):
    # trimesh imports Pillow only when it meets UVs: without it an OBJ loses its vt lines
    # silently and a .glb fails with a bare ModuleNotFoundError for PIL. So export checks for
    # Pillow, part of the export extra, before writing anything.
    monkeypatch.setitem(sys.modules, "PIL", None)
    sim = rustcloth.Simulation(small_scene())
    with pytest.raises(MissingExtra, match=r"'PIL'.*pip install 'rustcloth\[export\]'") as err:
        sim.export(tmp_path / f"cloth{suffix}")
    assert err.value.extra == "export"
    assert not (tmp_path / f"cloth{suffix}").exists()
    with pytest.raises(MissingExtra, match=r"rustcloth\[export\]"):
        export.recorder(tmp_path / "seq_##.obj")


def test_required_modules_by_suffix():
    assert export.required_modules("a/b.GLB") == ("trimesh", "PIL")
    assert export.required_modules("seq_####.obj") == ("trimesh", "PIL")
    assert export.required_modules("run.usdc") == ("pxr",)
    with pytest.raises(ValueError, match=r"cloth\.stl"):
        export.required_modules("cloth.stl")


def test_check_required_names_the_extra_of_the_missing_module(monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)
    with pytest.raises(MissingExtra, match=r"rustcloth\[usd\]"):
        export.check_required("run.usd")
    monkeypatch.setitem(sys.modules, "trimesh", None)
    with pytest.raises(MissingExtra, match=r"'trimesh'.*rustcloth\[export\]"):
        export.check_required("cloth.ply")


def test_usd_recorder_without_usd_core_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)
    with pytest.raises(MissingExtra, match=r"rustcloth\[usd\]"):
        export.UsdRecorder(tmp_path / "run.usd")


@pytest.mark.parametrize("suffix", [".usd", ".usda"])
def test_usd_run_has_every_frame_at_its_time_code(tmp_path, pxr, suffix):
    from pxr import Usd, UsdGeom

    fps = 20.0
    sim = rustcloth.Simulation(small_scene())
    frames = []
    with export.recorder(tmp_path / f"run{suffix}", fps) as rec:
        for _ in range(11):
            rec.add(sim)
            frames.append((sim.time, sim.positions, sim.normals, sim.velocities))
            sim.advance(1 / fps)
    stage = Usd.Stage.Open(str(tmp_path / f"run{suffix}"))
    assert stage.GetTimeCodesPerSecond() == fps and stage.GetFramesPerSecond() == fps
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 10.0)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    mesh = UsdGeom.Mesh(stage.GetDefaultPrim())
    assert mesh and mesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    points = mesh.GetPointsAttr()
    assert points.GetTimeSamples() == [float(k) for k in range(11)]
    for code, (t, x, n, v) in zip(points.GetTimeSamples(), frames, strict=True):
        assert code / fps == pytest.approx(t, abs=1e-12)
        assert np.array_equal(np.asarray(points.Get(code)), x)
        assert np.array_equal(np.asarray(mesh.GetNormalsAttr().Get(code)), n)
        assert np.array_equal(np.asarray(mesh.GetVelocitiesAttr().Get(code)), v)
        lo, hi = np.asarray(mesh.GetExtentAttr().Get(code))
        assert np.array_equal(lo, x.min(axis=0)) and np.array_equal(hi, x.max(axis=0))
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.vertex
    assert np.array_equal(np.asarray(st.Get(0.0)), export.grid_uvs(8, 6))


def test_usd_frames_land_on_whole_codes_when_dt_does_not_divide_the_frame_time(tmp_path, pxr):
    # At dt = 1 ms and 30 fps, frame k is at the step nearest k / 30 s (33 ms, 67 ms, ...):
    # its samples landed at codes 0.99, 2.01, ... though the docstring promised whole codes.
    from pxr import Usd, UsdGeom

    fps = 30.0
    sim = rustcloth.Simulation(small_scene())
    times = []
    with export.recorder(tmp_path / "run.usda", fps) as rec:
        for k in range(10):
            sim.step(round(k / fps / sim.dt) - sim.steps)
            rec.add(sim)
            times.append(sim.time)
    assert times[1] == pytest.approx(0.033) and times[2] == pytest.approx(0.067)
    stage = Usd.Stage.Open(str(tmp_path / "run.usda"))
    points = UsdGeom.Mesh(stage.GetDefaultPrim()).GetPointsAttr()
    assert points.GetTimeSamples() == [float(k) for k in range(10)]
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 9.0)


def test_usd_frames_between_whole_codes_keep_their_own_time(tmp_path, pxr):
    from pxr import Usd, UsdGeom

    sim = rustcloth.Simulation(small_scene())
    with export.recorder(tmp_path / "run.usda", fps=10.0) as rec:
        for _ in range(3):
            rec.add(sim)
            sim.step(50)  # half a frame: 0, 0.5, 1.0
    stage = Usd.Stage.Open(str(tmp_path / "run.usda"))
    points = UsdGeom.Mesh(stage.GetDefaultPrim()).GetPointsAttr()
    assert points.GetTimeSamples() == [0.0, 0.5, 1.0]


def test_usd_topology_follows_cuts(tmp_path, pxr):
    from pxr import Usd, UsdGeom

    sim = rustcloth.Simulation(small_scene())
    with export.UsdRecorder(tmp_path / "cut.usd", fps=10) as rec:
        rec.add(sim)
        before = sim.triangles
        sim.advance(0.1)
        rec.add(sim)
        sim.cut(27)
        sim.advance(0.1)
        rec.add(sim)
        after = sim.triangles
    stage = Usd.Stage.Open(str(tmp_path / "cut.usd"))
    mesh = UsdGeom.Mesh(stage.GetDefaultPrim())
    indices, counts = mesh.GetFaceVertexIndicesAttr(), mesh.GetFaceVertexCountsAttr()
    # Sampled at the first frame and again at the frame after the cut, held in between.
    assert indices.GetTimeSamples() == [0.0, 2.0] == counts.GetTimeSamples()
    assert np.array_equal(np.asarray(indices.Get(0.0)), before.ravel())
    assert np.array_equal(np.asarray(indices.Get(1.0)), before.ravel())
    assert np.array_equal(np.asarray(indices.Get(2.0)), after.ravel())
    assert list(counts.Get(2.0)) == [3] * len(after)
    assert len(mesh.GetPointsAttr().Get(2.0)) == 48  # points keep their count


def test_obj_sequence_writes_one_numbered_file_per_frame(tmp_path, trimesh):
    sim = rustcloth.Simulation(small_scene())
    positions = []
    with export.recorder(tmp_path / "seq" / "cloth_###.obj") as rec:
        for _ in range(3):
            rec.add(sim)
            positions.append(sim.positions)
            sim.step(20)
    names = sorted(p.name for p in (tmp_path / "seq").iterdir())
    assert names == ["cloth_000.obj", "cloth_001.obj", "cloth_002.obj"]
    for name, x in zip(names, positions, strict=True):
        np.testing.assert_allclose(obj_records(tmp_path / "seq" / name, "v"), x, atol=1e-6)


@pytest.mark.parametrize("path", ["run.obj", "cloth_##_##.obj", "cloth_##.ply", "run.txt"])
def test_recorder_refuses_paths_it_cannot_record_to(tmp_path, path):
    with pytest.raises(ValueError, match="cannot record|OBJ sequence pattern"):
        export.recorder(tmp_path / path)


def test_recorder_refuses_frames_after_close(tmp_path, pxr):
    sim = rustcloth.Simulation(small_scene())
    rec = export.UsdRecorder(tmp_path / "run.usda")
    rec.add(sim)
    rec.close()
    with pytest.raises(ValueError, match="closed"):
        rec.add(sim)


def test_exports_draw_the_cut_edge_and_usd_resamples_its_points(tmp_path, pxr):
    from pxr import Usd, UsdGeom

    sim = rustcloth.Simulation(small_scene())
    with export.UsdRecorder(tmp_path / "sever.usd", fps=10) as rec:
        rec.add(sim)
        sim.advance(0.1)
        y = float(sim.positions[:, 1].reshape(sim.ny, sim.nx)[2:4, 0].mean())
        x = sim.positions[:, 0]
        rays = [([float(x.min()) - 0.2, y, 2.0], [0, 0, -1]),
                ([float(x.max()) + 0.2, y, 2.0], [0, 0, -1])]
        assert sim.sever_stroke(rays) > 0
        rec.add(sim)
        mesh = export.to_mesh(sim)
        sources = sim.render_topology()[2]
    drawn = sim.render_mesh()
    assert np.array_equal(mesh.vertices, drawn.positions)
    assert np.array_equal(mesh.triangles, drawn.triangles) and len(mesh.uvs) > sim.num_particles
    stage = Usd.Stage.Open(str(tmp_path / "sever.usd"))
    usd = UsdGeom.Mesh(stage.GetDefaultPrim())
    # The cut vertices join the points at the frame of the cut, with UVs and velocities.
    assert len(usd.GetPointsAttr().Get(0.0)) == sim.num_particles
    assert len(usd.GetPointsAttr().Get(1.0)) == len(mesh.vertices)
    st = UsdGeom.PrimvarsAPI(usd).GetPrimvar("st")
    assert np.array_equal(np.asarray(st.Get(1.0)), mesh.uvs)
    velocities = np.asarray(usd.GetVelocitiesAttr().Get(1.0))
    assert np.array_equal(velocities, sim.velocities[sources])
    assert np.asarray(usd.GetFaceVertexIndicesAttr().Get(1.0)).max() >= sim.num_particles
