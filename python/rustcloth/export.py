"""The cloth as a triangle mesh, and files other tools read: OBJ, PLY and glTF binary frames
(through trimesh, ``pip install 'rustcloth[export]'``), a whole run as one USD file (through
usd-core, ``pip install 'rustcloth[usd]'``), or a run as a numbered OBJ sequence.

Every mesh is the drawn surface (:meth:`rustcloth.Simulation.render_mesh`). Vertex ``p < N`` is
particle ``p`` (row ``j * nx + i``), cut particles included: they stay as vertices that no
triangle uses, so a particle's index never shifts. After them come the cut vertices that put
the edge of a severed stroke or a tear where it crossed the springs (docs/cutting.md); their
number changes only when the topology does, and a USD file samples the point count, the UVs and
the faces again then.

>>> import rustcloth
>>> sim = rustcloth.Simulation("hanging")
>>> mesh = to_mesh(sim)
>>> mesh.vertices.shape, mesh.triangles.shape, mesh.uvs[sim.nx - 1].tolist()
((1024, 3), (1922, 3), [1.0, 0.0])
"""

from __future__ import annotations

import importlib.util
import math
import os
import re
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ._extras import MissingExtra
from .mesh import Mesh, grid_uvs

if TYPE_CHECKING:
    from .simulation import Simulation

# Mesh and grid_uvs are defined in rustcloth.mesh, where rustcloth.simulation takes them from
# without importing this module; they are part of this module's API too.
__all__ = [
    "MESH_FORMATS", "USD_FORMATS", "Mesh", "ObjSequenceRecorder", "Recorder", "UsdRecorder",
    "check_required", "export", "grid_uvs", "is_sequence", "recorder", "required_modules",
    "to_mesh",
]

#: Single-frame formats :func:`export` writes, by file suffix.
MESH_FORMATS = (".obj", ".ply", ".glb")
#: Suffixes :class:`UsdRecorder` writes (``.usd`` is binary crate, ``.usda`` text).
USD_FORMATS = (".usd", ".usda", ".usdc")

# What writing each kind of file imports, and the extra that installs it. trimesh imports
# Pillow only when it meets texture coordinates: without it an OBJ loses its ``vt`` lines
# silently and a ``.glb`` fails half-way, so Pillow is a need of every mesh file, not an extra
# dependency of trimesh's.
_MESH_NEEDS = ("trimesh", "PIL")
_USD_NEEDS = ("pxr",)


def required_modules(path: str | os.PathLike[str]) -> tuple[str, ...]:
    """The top-level modules writing ``path`` imports, by its suffix (a mesh file or an OBJ
    sequence: trimesh and Pillow; USD: ``pxr``), so that a command can check them before it
    starts a run. ``ValueError`` for a suffix nothing here writes.

    >>> required_modules("out/cloth.glb"), required_modules("run.usda")
    (('trimesh', 'PIL'), ('pxr',))
    """
    suffix = Path(path).suffix.lower()
    if suffix in USD_FORMATS:
        return _USD_NEEDS
    if suffix in MESH_FORMATS:
        return _MESH_NEEDS
    raise ValueError(
        f"cannot write {os.fspath(path)!r}: the suffix must be one of "
        f"{', '.join(USD_FORMATS + MESH_FORMATS)}"
    )


def check_required(path: str | os.PathLike[str]) -> None:
    """Raise :class:`MissingExtra` naming the extra (``export`` or ``usd``) when a module that
    writing ``path`` needs is not installed (:func:`required_modules`); ``ValueError`` for an
    unknown suffix. Cheap: it finds the modules without importing them."""
    modules = required_modules(path)
    extra = "usd" if modules == _USD_NEEDS else "export"
    what = "USD export" if extra == "usd" else f"{Path(path).suffix.lower()} export"
    for module in modules:
        if not _importable(module):
            raise MissingExtra(module, what, extra)


def _importable(module: str) -> bool:
    # A module set to None in sys.modules is one an import refuses (as tests simulate a
    # missing package); find_spec raises ValueError for it.
    try:
        return importlib.util.find_spec(module) is not None
    except ValueError:
        return False


def to_mesh(sim: Simulation) -> Mesh:
    """The simulation's current frame: the drawn mesh's positions, triangles, vertex normals
    and texture coordinates (:meth:`rustcloth.Simulation.render_mesh`)."""
    return sim.to_mesh()


def _trimesh() -> Any:
    try:
        import trimesh
    except ModuleNotFoundError as err:
        raise MissingExtra("trimesh", "mesh export", "export") from err
    return trimesh


def _as_trimesh(mesh: Mesh) -> Any:
    trimesh = _trimesh()
    return trimesh.Trimesh(
        vertices=mesh.vertices,
        faces=mesh.triangles,
        vertex_normals=mesh.normals,
        visual=trimesh.visual.TextureVisuals(uv=mesh.uvs),
        # Keep every vertex where it is: no merging, no reordering, no dropping of the unused
        # vertices of cut particles.
        process=False,
        validate=False,
    )


def export(sim: Simulation | Mesh, path: str | os.PathLike[str]) -> Path:
    """Write the current frame to ``path`` as Wavefront OBJ (``.obj``, with normals and UVs),
    binary PLY (``.ply``, with normals and UVs) or glTF binary (``.glb``), by suffix.

    Needs trimesh and Pillow (``pip install 'rustcloth[export]'``; :class:`MissingExtra`
    naming the extra otherwise, before anything is written).
    Raises ``ValueError`` for any other suffix. Returns the path written."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        raise ValueError(
            f"cannot export {str(path)!r}: the suffix must be one of {', '.join(MESH_FORMATS)}"
        )
    check_required(path)
    mesh = sim if isinstance(sim, Mesh) else to_mesh(sim)
    tm = _as_trimesh(mesh)
    if suffix == ".obj":
        # One file: no .mtl or texture beside it (the cloth has UVs but no material).
        data = tm.export(file_type="obj", include_normals=True, include_texture=True,
                         write_texture=False, mtl_name=None, header=None)
        text = "\n".join(line for line in data.splitlines()
                         if not line.startswith(("mtllib", "usemtl")))
        path.write_text(text + "\n", encoding="ascii")
    elif suffix == ".ply":
        path.write_bytes(tm.export(file_type="ply", encoding="binary", vertex_normal=True))
    else:
        path.write_bytes(tm.export(file_type="glb"))
    return path


class Recorder:
    """Writes a run frame by frame (:class:`UsdRecorder`, :class:`ObjSequenceRecorder`):
    ``add(sim)`` once per frame, then ``close()``, or use it as a context manager."""

    def add(self, sim: Simulation) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Finish the output; adding after this is an error."""

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class UsdRecorder(Recorder):
    """Writes a whole run as one USD file: a ``UsdGeom.Mesh`` at ``prim_path`` (the stage's
    default prim) with time-sampled ``points``, ``normals``, ``velocities`` and ``extent``, and
    its topology (``faceVertexCounts``, ``faceVertexIndices``) and texture coordinates (the
    primvar ``st``) sampled again whenever the cloth is cut (the cut vertices change the point
    count). Each cut vertex's velocity is its particle's.

    A frame added at simulated time ``t`` seconds is sampled at time code
    ``t * fps``; the stage's ``timeCodesPerSecond`` and ``framesPerSecond`` are ``fps``. A
    frame added within half a step of ``k / fps`` s (the nearest a run of whole steps comes to
    it) is sampled at the whole time code ``k``, so frames added every ``1 / fps`` s fall on
    whole time codes 0, 1, 2, ... whether or not ``dt`` divides ``1 / fps``. The stage is
    y-up, in metres. Needs usd-core (``pip install 'rustcloth[usd]'``).

    >>> with UsdRecorder("run.usd", fps=30) as rec:          # doctest: +SKIP
    ...     for _ in range(90):
    ...         rec.add(sim)
    ...         sim.advance(1 / 30)
    """

    def __init__(self, path: str | os.PathLike[str], fps: float = 30.0,
                 prim_path: str = "/Cloth") -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, not {fps!r}")
        try:
            from pxr import Sdf, Usd, UsdGeom, Vt  # type: ignore[import-untyped]  # no stubs
        except ModuleNotFoundError as err:
            raise MissingExtra("pxr", "USD export", "usd") from err
        self._Sdf, self._UsdGeom, self._Vt = Sdf, UsdGeom, Vt
        self.path = Path(path)
        self.fps = float(fps)
        self.frames = 0
        self._stage = Usd.Stage.CreateNew(str(self.path))
        self._stage.SetTimeCodesPerSecond(self.fps)
        self._stage.SetFramesPerSecond(self.fps)
        UsdGeom.SetStageUpAxis(self._stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self._stage, UsdGeom.LinearUnits.meters)
        self._mesh = UsdGeom.Mesh.Define(self._stage, prim_path)
        self._stage.SetDefaultPrim(self._mesh.GetPrim())
        self._mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        self._mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
        self._mesh.CreateDoubleSidedAttr(True)
        self._points = self._mesh.CreatePointsAttr()
        self._normals = self._mesh.CreateNormalsAttr()
        self._mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        self._velocities = self._mesh.CreateVelocitiesAttr()
        self._extent = self._mesh.CreateExtentAttr()
        self._counts = self._mesh.CreateFaceVertexCountsAttr()
        self._indices = self._mesh.CreateFaceVertexIndicesAttr()
        self._topology: int | None = None
        self._st: Any = None
        self._sources: npt.NDArray[np.uint32] = np.zeros(0, dtype=np.uint32)
        self._codes: list[float] = []
        self._closed = False

    def add(self, sim: Simulation) -> None:
        """Sample the simulation's current state at time code ``sim.time * fps``, or at the
        whole code ``k`` when ``sim.time`` is within half a step (``sim.dt / 2``) of
        ``k / fps``."""
        if self._closed:
            raise ValueError(f"the recorder of {str(self.path)!r} is closed")
        Vt, UsdGeom = self._Vt, self._UsdGeom
        code = self._code(sim.time, sim.dt)
        mesh = to_mesh(sim)
        if not self._codes:
            self._st = UsdGeom.PrimvarsAPI(self._mesh).CreatePrimvar(
                "st", self._Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
        if sim.topology_version != self._topology:
            self._topology = sim.topology_version
            self._sources = sim.render_topology()[2]
            self._st.Set(Vt.Vec2fArray.FromNumpy(mesh.uvs), code)
            self._counts.Set(Vt.IntArray.FromNumpy(
                np.full(len(mesh.triangles), 3, dtype=np.int32)), code)
            self._indices.Set(Vt.IntArray.FromNumpy(
                mesh.triangles.astype(np.int32).ravel()), code)
        points = Vt.Vec3fArray.FromNumpy(mesh.vertices)
        self._points.Set(points, code)
        self._normals.Set(Vt.Vec3fArray.FromNumpy(mesh.normals), code)
        self._velocities.Set(Vt.Vec3fArray.FromNumpy(
            np.ascontiguousarray(sim.velocities[self._sources], dtype=np.float32)), code)
        self._extent.Set(UsdGeom.PointBased.ComputeExtent(points), code)
        self._codes.append(code)
        self.frames += 1

    def _code(self, time: float, dt: float) -> float:
        # A simulation can only stop at whole steps, so frame k of a run taken every 1 / fps s
        # is at the step nearest k / fps, up to half a step away (at dt = 1 ms and 30 fps,
        # frame 1 is at 33 ms, code 0.99): that is still frame k, and lands on code k. Any
        # other time keeps its own code, as does a frame whose whole code is already taken.
        exact = time * self.fps
        whole = float(round(exact))
        code = whole if abs(exact - whole) <= 0.5 * dt * self.fps + 1e-9 else round(exact, 9)
        if self._codes and code <= self._codes[-1]:
            code = round(exact, 9)
        return code

    def close(self) -> None:
        """Set the stage's start and end time codes and save the file."""
        if self._closed:
            return
        self._closed = True
        if self._codes:
            self._stage.SetStartTimeCode(min(self._codes))
            self._stage.SetEndTimeCode(max(self._codes))
        self._stage.GetRootLayer().Save()


class ObjSequenceRecorder(Recorder):
    """Writes each added frame as its own OBJ file (normals and UVs included), numbered from 0:
    the run of ``#`` in ``pattern`` is replaced by the frame number, zero-padded to its length
    (``out/cloth_####.obj`` gives ``out/cloth_0000.obj``, ``out/cloth_0001.obj``, ...), as
    Blender's and Houdini's sequence loaders expect. Needs trimesh
    (``pip install 'rustcloth[export]'``)."""

    def __init__(self, pattern: str | os.PathLike[str]) -> None:
        pattern = str(pattern)
        runs = re.findall(r"#+", Path(pattern).name)
        if len(runs) != 1 or Path(pattern).suffix.lower() != ".obj":
            raise ValueError(
                f"an OBJ sequence pattern ends in .obj and has one run of '#' in its file name "
                f"for the frame number (e.g. out/cloth_####.obj), not {pattern!r}"
            )
        check_required(pattern)
        self.pattern = pattern
        self.paths: list[Path] = []

    def path_of(self, frame: int) -> Path:
        """The file frame number ``frame`` is written to."""
        p = Path(self.pattern)
        run = re.search(r"#+", p.name)
        assert run is not None
        name = p.name[:run.start()] + f"{frame:0{len(run.group())}d}" + p.name[run.end():]
        return p.with_name(name)

    def add(self, sim: Simulation) -> None:
        """Write the current frame as the next file of the sequence."""
        path = self.path_of(len(self.paths))
        path.parent.mkdir(parents=True, exist_ok=True)
        self.paths.append(export(sim, path))


def is_sequence(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names an OBJ sequence (a ``#`` in its file name)."""
    return "#" in Path(path).name


def recorder(path: str | os.PathLike[str], fps: float = 30.0) -> Recorder:
    """The recorder for ``path``: :class:`UsdRecorder` for ``.usd``, ``.usda``, ``.usdc``;
    :class:`ObjSequenceRecorder` for a ``.obj`` name with ``#`` in it. ``ValueError`` for any
    other path (single frames go through :func:`export`)."""
    if Path(path).suffix.lower() in USD_FORMATS:
        return UsdRecorder(path, fps)
    if is_sequence(path):
        return ObjSequenceRecorder(path)
    raise ValueError(
        f"cannot record a run to {str(path)!r}: use a USD file ({', '.join(USD_FORMATS)}) or an "
        f"OBJ sequence pattern such as out/cloth_####.obj"
    )
