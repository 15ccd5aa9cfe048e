"""The renderer: one method per pass, fed from persistent vertex buffers, skipping the work a
frame does not need (the shadow map when nothing moved, everything but the last pass when
nothing changed). Two quality tiers: ``full``, deferred (shadow map, G-buffer, fill light and
SSAO at half size, lighting or a debug view, FXAA, highlights, overlay); and ``software``,
for renderers without a GPU (shadow map, one forward pass shading each surface as it is
drawn, the sky behind it, a plain copy, highlights, overlay)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, cast

import moderngl
import numpy as np
import numpy.typing as npt

from ..camera import Camera, gl_bytes, light_view_projection
from . import constants as K
from . import meshes
from .layout import SceneLayout, box_corners
from .lights import PRESET_NAMES, LightPreset, key_direction, place_points, preset
from .shaders import load_program
from .tiers import SOFTWARE_SHADOW_SIZE, TIERS

F32 = npt.NDArray[np.float32]
VIEWS = K.VIEWS
_FLOOR_HALF_SIZE = 30.0  # m: far enough that fog hides its edge


class ClothSource(Protocol):
    """What the renderer reads from a :class:`rustcloth.Simulation` (or a stand-in)."""

    @property
    def nx(self) -> int: ...
    @property
    def ny(self) -> int: ...
    @property
    def num_particles(self) -> int: ...
    @property
    def topology_version(self) -> int: ...
    @property
    def positions(self) -> F32: ...
    @property
    def normals(self) -> F32: ...
    @property
    def velocities(self) -> F32: ...
    @property
    def triangles(self) -> npt.NDArray[np.uint32]: ...
    @property
    def pinned(self) -> npt.NDArray[np.bool_]: ...
    @property
    def scene(self) -> Any: ...
    def spring_strain(self) -> F32: ...
    def render_positions(self) -> tuple[F32, F32]: ...
    def render_topology(
        self,
    ) -> tuple[npt.NDArray[np.uint32], F32, npt.NDArray[np.uint32]]: ...
    def colliders(self) -> list[dict[str, Any]]: ...
    def collider_poses(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...


def layout_of(sim: ClothSource) -> SceneLayout:
    """The scene's layout from its dict and the cloth's current (rest) state: the one place
    the renderer and the viewer read ``sim.scene``, once per load or reset."""
    return SceneLayout.from_scene(sim.scene.to_dict(), sim.positions, sim.normals, sim.pinned)


@dataclass
class _Panel:
    texture: Any
    corner: str


@dataclass
class _Solid:
    """A rigid mesh drawn by the shadow and geometry passes at ``model``: a ``[[spheres]]``
    sphere (placed once) or collider ``collider`` (posed each frame from ``collider_poses``)."""

    vao: moderngl.VertexArray
    shadow_vao: moderngl.VertexArray
    forward_vao: moderngl.VertexArray
    model: F32
    material: K.Material
    collider: int | None = None
    # Whether its depth is pushed back (Renderer.depth_push): not a plane, on which cloth
    # lies flat, and whose two triangles span metres (a push interpolated across them would
    # be far from depth_push inside).
    pushed: bool = True


class Renderer:
    """Draws one simulation into any framebuffer.

    It draws the simulation's drawn mesh (``render_positions``, ``render_topology``: the
    particles, then the cut vertices along severed edges). Per frame, :meth:`update` uploads
    positions and normals into persistent vertex buffers with ``buffer.write``; the index
    buffer and the texture coordinates are rewritten only when ``topology_version`` changes
    (the vertex buffers grow then, if the cut vertices need more room), and the index buffer
    also when a sliver along a cut comes to wind against its vertex normals or stops
    (``_Slivers``). :meth:`render` then
    runs the passes. ``pass_timer``, when set, is called with each pass's name as it finishes
    (benches use it to time passes). ``depth_push`` (m, set per simulation: three quarters
    of the cloth's mean edge) is how far behind their surface the spheres' and colliders'
    depth is written, so that cloth bent over a solid's edge, whose flat triangles cut its
    corner, still covers it (``depth_push.glsl``).

    ``tier`` (one of :data:`TIERS`, settable at any time): ``software`` draws the lit view
    in one forward pass, lit per vertex, with a shadow map of :data:`SOFTWARE_SHADOW_SIZE`,
    no SSAO and no FXAA; the debug views and the scalar views draw as in ``full``.
    """

    def __init__(self, ctx: moderngl.Context, sim: ClothSource, size: tuple[int, int],
                 shadow_size: int = 1024, lights: str = "studio", tier: str = "full") -> None:
        if tier not in TIERS:
            raise ValueError(f"tier must be one of {', '.join(TIERS)}, not {tier!r}")
        self.ctx = ctx
        self._tier = tier
        self.view = "lit"
        self.shadows = True
        self.fxaa = True
        self.ssao = False
        self.point_lights = True
        self.highlight: int | None = None
        self._show_colliders = True
        self._shadow_positions: F32 | None = None  # the cloth the shadow map was drawn for
        self.pass_timer: Callable[[str], None] | None = None
        self.lights: LightPreset = preset(lights)

        self.geometry = load_program(ctx, "geometry.vert", "geometry.frag")
        self.shadow_prog = load_program(ctx, "shadow.vert", "shadow.frag")
        self.lighting = load_program(ctx, "fullscreen.vert", "lighting.frag")
        self.debug = load_program(ctx, "fullscreen.vert", "debug.frag")
        self.fxaa_prog = load_program(ctx, "fullscreen.vert", "fxaa.frag")
        self.fill_prog = load_program(ctx, "fullscreen.vert", "fill.frag")
        self.lines = load_program(ctx, "lines.vert", "lines.frag")
        self.overlay_prog = load_program(ctx, "overlay.vert", "overlay.frag")
        self.forward = load_program(ctx, "forward.vert", "forward.frag")
        self.forward_cloth = load_program(ctx, "forward_cloth.vert", "forward_cloth.frag")
        self.sky_prog = load_program(ctx, "fullscreen.vert", "sky.frag")
        # Full-screen passes draw one triangle from gl_VertexID: no vertex buffers.
        self.fullscreen = {
            p: ctx.vertex_array(p, [])
            for p in (self.lighting, self.debug, self.fxaa_prog, self.fill_prog, self.sky_prog)
        }

        self._full_shadow_size = shadow_size
        self._make_shadow_map()

        # One unit sphere for every ``[[spheres]]`` sphere, scaled by its model matrix.
        (self.sphere_vbo, self.sphere_ibo, self.sphere_vao, self.sphere_shadow_vao,
         self.sphere_forward_vao) = self._solid_buffers(meshes.uv_sphere(32, 64))
        # Its shadow from a quarter of the vertices, which every redraw of the map pays for:
        # the outline is off by r (1 - cos(pi / 32)) = 0.5 % of the radius, under a texel.
        shadow_v, shadow_i = meshes.uv_sphere(16, 32)
        self.sphere_shadow_vbo, self.sphere_shadow_ibo = ctx.buffer(shadow_v), ctx.buffer(shadow_i)
        self.sphere_shadow_vao = self._mesh_vao(self.shadow_prog, self.sphere_shadow_vbo,
                                                self.sphere_shadow_ibo)
        self._collider_buffers: list[moderngl.Buffer] = []
        # Markers are a few pixels across: a coarse sphere (vertex work is not free here).
        marker_v, marker_i = meshes.uv_sphere(8, 16)
        self.marker_vbo = ctx.buffer(marker_v)
        self.marker_ibo = ctx.buffer(marker_i)
        self.marker_vao = self._mesh_vao(self.geometry, self.marker_vbo, self.marker_ibo)
        self.marker_forward_vao = self._mesh_vao(self.forward, self.marker_vbo, self.marker_ibo)

        self.stroke_vbo = ctx.buffer(reserve=4096 * 12)
        self.stroke_vao = ctx.vertex_array(self.lines, [(self.stroke_vbo, "3f", "in_position")])
        self.stroke_count = 0
        self._stroke_version = -1

        self.panels: dict[str, _Panel] = {}
        self.overlay_vao = ctx.vertex_array(self.overlay_prog, [])

        self.size = self.inner = (0, 0)
        self.scale = 1.0
        self._lit_key: tuple[Any, ...] | None = None
        self._inv_view_proj = np.identity(4, dtype=np.float32)
        self._eye = np.zeros(3)
        self.resize(size)
        self.set_simulation(sim)

    @property
    def tier(self) -> str:
        """The quality tier, one of :data:`TIERS`."""
        return self._tier

    @tier.setter
    def tier(self, tier: str) -> None:
        if tier not in TIERS:
            raise ValueError(f"tier must be one of {', '.join(TIERS)}, not {tier!r}")
        if tier != self._tier:
            self._tier = tier
            self._make_shadow_map()
            self.set_lights(self.lights.name)  # the shadow tolerance follows the map's texel

    def _make_shadow_map(self) -> None:
        """The key light's shadow map at the tier's size (drawn again before its next use)."""
        size = (self._full_shadow_size if self._tier == "full"
                else min(self._full_shadow_size, SOFTWARE_SHADOW_SIZE))
        for name in ("shadow_fbo", "shadow_depth"):
            old = getattr(self, name, None)
            if old is not None:
                old.release()
        self.shadow_depth = self.ctx.depth_texture((size, size))
        self.shadow_depth.compare_func = "<="
        # Linear filtering of a compare texture gives a free 2x2 PCF on every tap.
        self.shadow_depth.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.shadow_depth.repeat_x = self.shadow_depth.repeat_y = False
        self.shadow_fbo = self.ctx.framebuffer(depth_attachment=self.shadow_depth)
        self.shadow_size = size
        self._shadow_positions = None

    @property
    def show_colliders(self) -> bool:
        """Whether the scene's colliders and spheres are drawn (off: cloth, floor, markers)."""
        return self._show_colliders

    @show_colliders.setter
    def show_colliders(self, show: bool) -> None:
        if show != self._show_colliders:
            self._show_colliders = show
            self._shadow_positions = None  # they cast shadows, or no longer

    # -- set-up ----------------------------------------------------------------------------
    def _mesh_vao(
        self, prog: moderngl.Program, vbo: moderngl.Buffer, ibo: moderngl.Buffer
    ) -> moderngl.VertexArray:
        # Position, normal, uv per vertex; a program gets the attributes it reads.
        if "in_normal" not in prog:
            fmt: list[tuple[Any, ...]] = [(vbo, "3f 12x 8x", "in_position")]
        elif "in_uv" not in prog:
            fmt = [(vbo, "3f 3f 8x", "in_position", "in_normal")]
        else:
            fmt = [(vbo, "3f 3f 2f", "in_position", "in_normal", "in_uv")]
        return self.ctx.vertex_array(prog, fmt, index_buffer=ibo, index_element_size=4)

    def _solid_buffers(self, mesh: meshes.Mesh) -> tuple[
            moderngl.Buffer, moderngl.Buffer, moderngl.VertexArray, moderngl.VertexArray,
            moderngl.VertexArray]:
        """A mesh uploaded once, with its vertex arrays for the geometry, shadow and forward
        passes."""
        vbo, ibo = self.ctx.buffer(mesh[0]), self.ctx.buffer(mesh[1])
        return (vbo, ibo, self._mesh_vao(self.geometry, vbo, ibo),
                self._mesh_vao(self.shadow_prog, vbo, ibo),
                self._mesh_vao(self.forward, vbo, ibo))

    def _build_solids(self, sim: ClothSource) -> None:
        """The spheres and the colliders, each collider's mesh built and uploaded once here
        (per load or reset); their poses come in :meth:`update`."""
        for buffer in self._collider_buffers:
            buffer.release()
        self._collider_buffers = []
        self.solids = [_Solid(self.sphere_vao, self.sphere_shadow_vao, self.sphere_forward_vao,
                              meshes.translate_scale(s.center, s.radius), K.SPHERE)
                       for s in self.layout.spheres]
        for k, collider in enumerate(sim.colliders()):
            vbo, ibo, vao, shadow_vao, forward_vao = self._solid_buffers(
                meshes.collider_mesh(collider, _FLOOR_HALF_SIZE))
            self._collider_buffers += [vbo, ibo]
            self.solids.append(_Solid(vao, shadow_vao, forward_vao,
                                      np.identity(4, dtype=np.float32), K.COLLIDER, k,
                                      pushed=collider["shape"] != "plane"))
        self._poses: tuple[npt.NDArray[np.float64], ...] | None = None

    def _pose_colliders(self) -> None:
        """Each collider's model matrix from its pose now; the shadow map and the kept lit
        image are redrawn when a pose changed."""
        positions, rotations = self.sim.collider_poses()
        last = self._poses
        if last is not None and np.array_equal(last[0], positions) and np.array_equal(
                last[1], rotations):
            return
        self._poses = (positions, rotations)
        for solid in self.solids:
            if solid.collider is not None:
                solid.model = meshes.pose_matrix(positions[solid.collider],
                                                 rotations[solid.collider])
        self._shadow_positions = None
        self._state_serial += 1

    def resize(self, size: tuple[int, int], scale: float | None = None) -> None:
        """The output is ``size`` pixels; the 3D passes draw ``scale`` (0.25..1, default:
        as before) of it each way, and the last pass scales their image up. (Re)creates the
        G-buffer, the lit image and the half-size fill image when that changes."""
        size = (max(1, int(size[0])), max(1, int(size[1])))
        scale = self.scale if scale is None else min(1.0, max(0.25, float(scale)))
        inner = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
        if size == self.size and inner == self.inner:
            return
        for name in ("gbuffer", "g_normal", "g_albedo", "g_depth", "lit_fbo", "forward_fbo",
                     "forward_depth", "lit", "fill_fbo", "fill"):
            old = getattr(self, name, None)
            if old is not None:
                old.release()
        ctx = self.ctx
        self.size, self.scale, self.inner = size, scale, inner
        size = inner
        self.g_normal = ctx.texture(size, 4, dtype="f2")
        self.g_albedo = ctx.texture(size, 4, dtype="f1")
        self.g_depth = ctx.depth_texture(size)
        for tex in (self.g_normal, self.g_albedo, self.g_depth):
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False
        self.g_depth.compare_func = ""  # read as plain depth
        self.gbuffer = ctx.framebuffer(color_attachments=[self.g_normal, self.g_albedo],
                                       depth_attachment=self.g_depth)
        self.lit = ctx.texture(size, 4, dtype="f1")
        self.lit.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.lit.repeat_x = self.lit.repeat_y = False
        self.lit_fbo = ctx.framebuffer(color_attachments=[self.lit])
        # The software tier's forward pass draws into the lit image with a depth buffer.
        self.forward_depth = ctx.depth_renderbuffer(size)
        self.forward_fbo = ctx.framebuffer(color_attachments=[self.lit],
                                           depth_attachment=self.forward_depth)
        # rgb: the point lights' irradiance (can exceed 1); a: ambient occlusion.
        self.fill = ctx.texture((max(1, size[0] // 2), max(1, size[1] // 2)), 4, dtype="f2")
        self.fill.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.fill.repeat_x = self.fill.repeat_y = False
        self.fill_fbo = ctx.framebuffer(color_attachments=[self.fill])
        self._lit_key = None

    def set_simulation(self, sim: ClothSource, layout: SceneLayout | None = None) -> None:
        """Bind a (new or reset) simulation: cloth buffers sized for it, and the scene's
        layout, static meshes, shadow box and lights (``layout``: already read by the caller,
        else read here)."""
        ctx = self.ctx
        for name in ("cloth_pos", "cloth_nrm", "cloth_uv", "cloth_scalar", "cloth_ibo",
                     "floor_vbo", "floor_ibo", "floor_grid_vbo", "floor_grid_ibo"):
            old = getattr(self, name, None)
            if old is not None:
                old.release()
        self.sim = sim
        self.layout = layout_of(sim) if layout is None else layout
        n = sim.num_particles
        self.cloth_pos = ctx.buffer(reserve=n * 12, dynamic=True)
        self.cloth_nrm = ctx.buffer(reserve=n * 12, dynamic=True)
        self.cloth_uv = ctx.buffer(meshes.cloth_uv(sim.nx, sim.ny), dynamic=True)
        self.cloth_scalar = ctx.buffer(reserve=n * 4, dynamic=True)
        self.cloth_ibo = ctx.buffer(reserve=max(1, sim.triangles.nbytes), dynamic=True)
        self._sources = np.arange(n, dtype=np.uint32)
        self.cloth_vao = ctx.vertex_array(
            self.geometry,
            [
                (self.cloth_pos, "3f", "in_position"),
                (self.cloth_nrm, "3f", "in_normal"),
                (self.cloth_uv, "2f", "in_uv"),
                (self.cloth_scalar, "f", "in_scalar"),
            ],
            index_buffer=self.cloth_ibo, index_element_size=4,
        )
        self.cloth_shadow_vao = ctx.vertex_array(
            self.shadow_prog, [(self.cloth_pos, "3f", "in_position")],
            index_buffer=self.cloth_ibo, index_element_size=4,
        )
        self.cloth_forward_vao = ctx.vertex_array(
            self.forward_cloth,
            [
                (self.cloth_pos, "3f", "in_position"),
                (self.cloth_nrm, "3f", "in_normal"),
                (self.cloth_uv, "2f", "in_uv"),
            ],
            index_buffer=self.cloth_ibo, index_element_size=4,
        )
        self._topology = -1
        self.index_count = 0
        self._slivers = _Slivers(np.zeros((0, 3), dtype=np.uint32), n)
        # Three quarters of the cloth's mean edge: deeper than a triangle bent over a solid's
        # edge cuts in (up to a third of an edge at a right-angled fold over a sharp edge);
        # round_tablecloth's table still showed through in a pixel at half.
        edges = sim.positions[sim.triangles] - sim.positions[np.roll(sim.triangles, 1, axis=1)]
        self.depth_push = 0.75 * float(np.linalg.norm(edges, axis=2).mean()) if edges.size else 0.0
        self.positions = np.zeros((n, 3), dtype=np.float32)
        self._shadow_positions = None
        self._state_serial = 0

        lay = self.layout
        center = lay.center
        floor_v, floor_i = meshes.floor_quad((float(center[0]), float(center[2])), lay.ground,
                                             _FLOOR_HALF_SIZE)
        self.floor_vbo = ctx.buffer(floor_v)
        self.floor_ibo = ctx.buffer(floor_i)
        self.floor_vao = self._mesh_vao(self.geometry, self.floor_vbo, self.floor_ibo)
        # The software tier lights the floor per vertex: a grid, fine where the lights are.
        grid_v, grid_i = meshes.floor_grid((float(center[0]), float(center[2])), lay.ground,
                                           _FLOOR_HALF_SIZE, 0.04 * lay.span + 0.02)
        self.floor_grid_vbo = ctx.buffer(grid_v)
        self.floor_grid_ibo = ctx.buffer(grid_i)
        self.floor_forward_vao = self._mesh_vao(self.forward, self.floor_grid_vbo,
                                                self.floor_grid_ibo)
        self._build_solids(sim)
        self.set_lights(self.lights.name)
        self.update()

    def set_lights(self, name: str) -> None:
        """Switch to a light preset: key direction, its shadow box, sky and point lights."""
        lay = self.layout
        self.lights = preset(name)
        self.light_dir = key_direction(self.lights, lay.view_azimuth)
        # The shadow map covers the cloth's reach, the spheres and where their shadows fall
        # on the ground, and no more.
        lo = lay.reach_min.copy()
        lo[1] = min(float(lo[1]), lay.ground)
        corners = box_corners(lo, lay.reach_max)
        d = self.light_dir
        on_ground = corners + ((lay.ground - corners[:, 1]) / min(float(d[1]), -0.05))[:, None] * d
        self.light_view_proj = light_view_projection(d, np.vstack([corners, on_ground]))
        texel = float(np.max(lay.reach_max - lay.reach_min)) * 2.5 / self.shadow_size
        self._shadow_tolerance = 0.25 * texel
        focus = np.array([lay.center[0], lay.ground, lay.center[2]], dtype=np.float32)
        self.points = place_points(self.lights, focus, lay.span, lay.ground)
        self._shadow_positions = None
        self._lit_key = None

    def cycle_lights(self) -> str:
        """The next light preset; returns its name."""
        k = PRESET_NAMES.index(self.lights.name)
        self.set_lights(PRESET_NAMES[(k + 1) % len(PRESET_NAMES)])
        return self.lights.name

    # -- per frame -------------------------------------------------------------------------
    def update(self) -> None:
        """Upload the simulation's current state (the one per-frame position upload)."""
        sim = self.sim
        if sim.topology_version != self._topology:
            tris, uvs, self._sources = sim.render_topology()
            self._slivers = _Slivers(tris, sim.num_particles)
            _write_growing(self.cloth_ibo, self._slivers.triangles)
            _write_growing(self.cloth_uv, uvs)
            for buffer, width in ((self.cloth_pos, 12), (self.cloth_nrm, 12),
                                  (self.cloth_scalar, 4)):
                if len(uvs) * width > buffer.size:
                    buffer.orphan(len(uvs) * width)
            self.index_count = tris.size
            self._topology = sim.topology_version
            self.positions = np.zeros((0, 3), dtype=np.float32)  # upload them below
            self._shadow_positions = None
            self._state_serial += 1
        positions, normals = sim.render_positions()
        if not np.array_equal(positions, self.positions):
            self.positions = positions
            self.cloth_pos.write(positions)
            self.cloth_nrm.write(normals)
            if self._slivers.mark(positions, normals):
                self.cloth_ibo.write(self._slivers.triangles)
            self._state_serial += 1
        if self.view in K.SCALAR_VIEWS:
            self.cloth_scalar.write(self._scalar(self.view))
            self._state_serial += 1
        if any(solid.collider is not None for solid in self.solids):
            self._pose_colliders()

    def invalidate_topology(self) -> None:
        """Force an index upload next frame (after ``reset()``, whatever its versions do)."""
        self._topology = -1

    def _scalar(self, view: str) -> F32:
        # Per particle, then per drawn vertex: a cut vertex shows its particle's value.
        sim = self.sim
        if view == "strain":
            value = np.asarray(sim.spring_strain(), dtype=np.float32)
        elif view == "speed":
            value = np.linalg.norm(sim.velocities, axis=1).astype(np.float32)
        else:
            value = np.asarray(sim.pinned, dtype=np.float32)
            if self.highlight is not None and 0 <= self.highlight < len(value):
                value[self.highlight] = 2.0
        return np.ascontiguousarray(value[self._sources], dtype=np.float32)

    def sync_stroke(self, segments: F32, version: int) -> None:
        """Upload the cut stroke (world-space segment end points, (M*2, 3)) only when its
        ``version`` changed, so a frame without cutting allocates nothing here."""
        if version == self._stroke_version:
            return
        self._stroke_version = version
        data = np.ascontiguousarray(segments, dtype=np.float32).reshape(-1, 3)
        if data.nbytes > self.stroke_vbo.size:
            self.stroke_vbo.orphan(2 * data.nbytes)
        if data.size:
            self.stroke_vbo.write(data)
        self.stroke_count = len(data) - len(data) % 2

    def set_panel(self, name: str, image: npt.NDArray[np.uint8] | None,
                  corner: str = "top-left") -> None:
        """An RGBA8 image (rows top to bottom) drawn at a ``corner`` of the output
        ("top-left", "bottom-left", "top-right"), or None to remove panel ``name``."""
        old = self.panels.get(name)
        if image is None:
            if old is not None:
                old.texture.release()
                del self.panels[name]
            return
        h, w = image.shape[:2]
        if old is None or old.texture.size != (w, h):
            if old is not None:
                old.texture.release()
            old = _Panel(self.ctx.texture((w, h), 4, dtype="f1"), corner)
            self.panels[name] = old
        old.corner = corner
        # GL textures start at the bottom row.
        old.texture.write(np.ascontiguousarray(image[::-1]))

    def render(self, target: moderngl.Framebuffer, camera: Camera) -> None:
        """Run the passes into ``target``."""
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        lit_view = self.view not in K.GBUFFER_VIEWS
        forward = self.tier == "software" and self.view == "lit"
        # The lit image is kept (and anti-aliased or scaled up by the last pass) unless it
        # can go straight to the target: a debug view at full scale.
        retained = (self.fxaa and lit_view) or self.inner != self.size or forward
        key = (self._state_serial, camera.view_projection.tobytes(), self.view, self.ssao,
               self.shadows, self.point_lights, self.lights.name, self.inner, self.highlight,
               self.show_colliders, self.tier)
        if forward:
            if key != self._lit_key:
                self._shadow_pass()
                self._forward_pass(camera)
                self._lit_key = key
        elif not (retained and key == self._lit_key):
            self._shadow_pass()
            self._geometry_pass(camera)
            ctx.disable(moderngl.DEPTH_TEST)
            if lit_view:
                self._fill_pass(camera)
            out = self.lit_fbo if retained else target
            if lit_view:
                self._lighting_pass(camera, out)
            else:
                self._debug_pass(camera, out)
            self._lit_key = key if retained else None
        ctx.disable(moderngl.DEPTH_TEST)
        if forward and self.inner == self.size:
            self._copy_pass(target)
        elif retained:
            self._fxaa_pass(target)
        self._stroke_pass(target, camera)
        self._overlay_pass(target)

    # -- the passes ------------------------------------------------------------------------
    def _done(self, name: str) -> None:
        if self.pass_timer is not None:
            self.pass_timer(name)

    def _shadow_pass(self) -> None:
        # Shadow: depth from the key light, redrawn only when the cloth moved by more than a
        # quarter texel (or the topology, lights or scene changed). Double-sided cloth shadows
        # itself; slope-scaled polygon offset keeps the receivers free of acne.
        if not self.shadows:
            return
        last = self._shadow_positions
        if last is not None and len(last) == len(self.positions) and (
                float(np.abs(self.positions - last).max(initial=0.0)) < self._shadow_tolerance):
            return
        self._shadow_positions = self.positions.copy()
        ctx = self.ctx
        self.shadow_fbo.use()
        self.shadow_fbo.clear(depth=1.0)
        ctx.polygon_offset = (1.5, 2.0)
        _uniforms(self.shadow_prog, light_view_proj=self.light_view_proj,
                  model=np.identity(4, dtype=np.float32))
        if self.index_count:
            self.cloth_shadow_vao.render(vertices=self.index_count)
        for solid in self._shown_solids():
            _uniforms(self.shadow_prog, model=solid.model)
            solid.shadow_vao.render()
        ctx.polygon_offset = (0.0, 0.0)
        self._done("shadow")

    def _geometry_pass(self, camera: Camera) -> None:
        # Geometry: every surface into the G-buffer (normal, albedo + material id, depth),
        # nearest first so the floor's hidden pixels fail the depth test early.
        g = self.geometry
        self._begin_surfaces(self.gbuffer, (g,), camera, alpha=0.0)
        lay = self.layout
        _uniforms(g, view=K.VIEW_IDS[self.view],
                  grid_cells=(float(lay.grid[0] - 1), float(lay.grid[1] - 1)))
        self._draw_surfaces(g, g, self.cloth_vao, [s.vao for s in self.solids],
                            self.marker_vao, self.floor_vao)
        self._done("geometry")

    def _begin_surfaces(self, fbo: moderngl.Framebuffer, progs: tuple[moderngl.Program, ...],
                        camera: Camera, alpha: float) -> None:
        """Clear ``fbo`` (colour to black with ``alpha``) and give ``progs`` the camera and the
        cloth's sides and size, for :meth:`_draw_surfaces`."""
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, alpha, depth=1.0)
        view_proj = camera.view_projection
        self._inv_view_proj = np.linalg.inv(view_proj.astype(np.float64)).astype(np.float32)
        self._eye = np.asarray(camera.eye, dtype=np.float64)
        lay = self.layout
        for prog in progs:
            _uniforms(prog, view_proj=view_proj, front_is_winding=lay.front_is_winding,
                      cloth_size=lay.cloth_size, eye=tuple(camera.eye))

    def _draw_surfaces(self, cloth_prog: moderngl.Program, prog: moderngl.Program,
                       cloth: moderngl.VertexArray, solids: list[moderngl.VertexArray],
                       marker: moderngl.VertexArray, floor: moderngl.VertexArray) -> None:
        """The cloth with ``cloth_prog``, then spheres and colliders, markers, floor (nearest
        first) with ``prog``, through the vertex arrays given for them (``solids``: one per
        :attr:`solids`)."""
        lay = self.layout
        if self.index_count:
            _uniforms(cloth_prog, model=np.identity(4, dtype=np.float32),
                      material=K.CLOTH_FRONT.id, base_color=K.srgb_to_linear(K.CLOTH_FRONT.color),
                      first_cut_vertex=self.sim.num_particles)
            cloth.render(vertices=self.index_count)
        for solid, vao in zip(self.solids, solids, strict=True):
            if self.show_colliders:
                _uniforms(prog, depth_push=self.depth_push if solid.pushed else 0.0)
                self._draw_mesh(prog, vao, solid.model, solid.material.id,
                                K.srgb_to_linear(solid.material.color))
        _uniforms(prog, depth_push=0.0)
        if self.highlight is not None and 0 <= self.highlight < len(self.positions):
            model = meshes.translate_scale(self.positions[self.highlight], 0.9 * lay.spacing)
            self._draw_mesh(prog, marker, model, K.MARKER.id, K.srgb_to_linear(K.MARKER.color))
        if self.view == "lit" and self.point_lights:
            size = 0.015 * lay.span + 0.02
            for pos, color in zip(self.points.positions, self.points.marker_colors, strict=True):
                self._draw_mesh(prog, marker, meshes.translate_scale(pos, size), K.LIGHT.id,
                                (float(color[0]), float(color[1]), float(color[2])))
        self._draw_mesh(prog, floor, np.identity(4, dtype=np.float32), K.FLOOR.id,
                        K.srgb_to_linear(K.FLOOR.color))

    def _shown_solids(self) -> list[_Solid]:
        return self.solids if self.show_colliders else []

    def _point_uniforms(self) -> dict[str, Any]:
        points = self.points
        pad = K.MAX_POINT_LIGHTS - len(points)
        return {"num_points": len(points) if self.view == "lit" and self.point_lights else 0,
                "point_pos": np.pad(points.positions, ((0, pad), (0, 0))),
                "point_color": np.pad(points.colors, ((0, pad), (0, 0))),
                "point_reach": np.pad(points.reaches, (0, pad))}

    def _fill_pass(self, camera: Camera) -> None:
        # Fill: the point lights' diffuse light and (when on) SSAO, at half size.
        self.fill_fbo.use()
        a = self.fill_prog
        _bind(a, {"g_normal": self.g_normal, "g_albedo": self.g_albedo,
                  "g_depth": self.g_depth})
        _uniforms(a, view_proj=camera.view_projection, inv_view_proj=self._inv_view_proj,
                  eye=tuple(camera.eye), radius=0.1 * self.layout.span,
                  ao_enabled=self.ssao and self.view == "lit", **self._point_uniforms())
        self.fullscreen[a].render(moderngl.TRIANGLES, vertices=3)
        self._done("fill")

    def _lighting_pass(self, camera: Camera, out: moderngl.Framebuffer) -> None:
        # Lighting: key light with shadows, point lights, ambient, fog; tone-mapped sRGB out.
        out.use()
        lp = self.lighting
        _bind(lp, {"g_normal": self.g_normal, "g_albedo": self.g_albedo,
                   "g_depth": self.g_depth, "shadow_map": self.shadow_depth,
                   "fill_map": self.fill})
        _uniforms(lp, inv_view_proj=self._inv_view_proj,
                  scalar_view=self.view in K.SCALAR_VIEWS, **self._light_uniforms(camera))
        self.fullscreen[lp].render(moderngl.TRIANGLES, vertices=3)
        self._done("lighting")

    def _light_uniforms(self, camera: Camera) -> dict[str, Any]:
        """The key light, its shadow map, sky, ambient, point lights, fog and exposure: what
        the lighting pass and the forward pass both shade with."""
        lights = self.lights
        distance = float(np.linalg.norm(camera.eye - camera.target))
        return {"light_view_proj": self.light_view_proj, "eye": tuple(camera.eye),
                "key_dir": tuple(self.light_dir),
                "key_color": _scaled(lights.key_color, lights.key_intensity),
                "shadows_enabled": self.shadows, "shadow_texel": 1.0 / self.shadow_size,
                "sky_zenith": K.srgb_to_linear(lights.sky_zenith),
                "sky_horizon": K.srgb_to_linear(lights.sky_horizon),
                "ground_color": K.srgb_to_linear(lights.ground), "ambient": lights.ambient,
                "fog_range": (distance + 1.0 * self.layout.span, distance + 14.0),
                "exposure": lights.exposure, **self._point_uniforms()}

    def _forward_pass(self, camera: Camera) -> None:
        # Forward (software tier): every surface shaded as it is drawn into the lit image,
        # nearest first so hidden pixels fail the depth test before shading; then the sky at
        # the far plane, paid only where nothing was drawn.
        ctx = self.ctx
        fp, fc = self.forward, self.forward_cloth
        self._begin_surfaces(self.forward_fbo, (fp, fc), camera, alpha=1.0)
        light = self._light_uniforms(camera)
        for prog in (fp, fc):
            _bind(prog, {"shadow_map": self.shadow_depth})
            _uniforms(prog, **light)
        self._draw_surfaces(fc, fp, self.cloth_forward_vao,
                            [s.forward_vao for s in self.solids], self.marker_forward_vao,
                            self.floor_forward_vao)
        ctx.depth_func = "<="
        sky = self.sky_prog
        lights = self.lights
        _uniforms(sky, ndc_depth=1.0, inv_view_proj=self._inv_view_proj, eye=tuple(camera.eye),
                  sky_zenith=K.srgb_to_linear(lights.sky_zenith),
                  sky_horizon=K.srgb_to_linear(lights.sky_horizon), exposure=lights.exposure)
        self.fullscreen[sky].render(moderngl.TRIANGLES, vertices=3)
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)
        self._done("forward")

    def _debug_pass(self, camera: Camera, out: moderngl.Framebuffer) -> None:
        # Debug: one raw G-buffer channel (or the shadow map) instead of lighting.
        out.use()
        d = self.debug
        _bind(d, {"g_normal": self.g_normal, "g_albedo": self.g_albedo,
                  "g_depth": self.g_depth, "shadow_depth": self.shadow_depth})
        self.shadow_depth.compare_func = ""
        distance = float(np.linalg.norm(camera.eye - camera.target))
        _uniforms(d, view=K.VIEW_IDS[self.view], inv_view_proj=self._inv_view_proj,
                  eye=tuple(camera.eye), depth_range=2.0 * distance,
                  viewport=(float(self.inner[0]), float(self.inner[1])))
        self.fullscreen[d].render(moderngl.TRIANGLES, vertices=3)
        self.shadow_depth.compare_func = "<="
        self._done("debug")

    def _fxaa_pass(self, target: moderngl.Framebuffer) -> None:
        # FXAA: anti-alias the tone-mapped image (and scale it up) into the caller's target.
        target.use()
        self.ctx.viewport = (0, 0, *self.size)
        f = self.fxaa_prog
        _bind(f, {"image": self.lit})
        w, h = self.inner
        _uniforms(f, texel=(1.0 / w, 1.0 / h), enabled=self.fxaa and self.tier == "full"
                  and self.view not in K.GBUFFER_VIEWS)
        self.fullscreen[f].render(moderngl.TRIANGLES, vertices=3)
        self._done("fxaa")

    def _copy_pass(self, target: moderngl.Framebuffer) -> None:
        # Copy (software tier at full scale): the lit image into the caller's target by a
        # framebuffer blit, a memory copy where a textured pass would filter every pixel.
        self.ctx.copy_framebuffer(target, self.forward_fbo)
        self._done("copy")

    def _stroke_pass(self, target: moderngl.Framebuffer, camera: Camera) -> None:
        # Highlights: the cut stroke on top of everything, so it stays visible behind folds.
        if not self.stroke_count:
            return
        target.use()
        _uniforms(self.lines, view_proj=camera.view_projection, color=(1.0, 0.9, 0.15, 1.0))
        self.stroke_vao.render(moderngl.LINES, vertices=self.stroke_count)
        self._done("stroke")

    def _overlay_pass(self, target: moderngl.Framebuffer) -> None:
        # Overlay: the text and legend panels, alpha-blended at their corners.
        if not self.panels:
            return
        ctx = self.ctx
        target.use()
        w, h = self.size
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        _uniforms(self.overlay_prog, text=0)
        for panel in self.panels.values():
            pw, ph = panel.texture.size
            panel.texture.use(0)
            x0 = 1.0 - 2.0 * pw / w if panel.corner.endswith("right") else -1.0
            y0 = -1.0 if panel.corner.startswith("bottom") else 1.0 - 2.0 * ph / h
            _uniforms(self.overlay_prog, rect=(x0, y0, x0 + 2.0 * pw / w, y0 + 2.0 * ph / h))
            self.overlay_vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
        ctx.disable(moderngl.BLEND)
        self._done("overlay")

    @staticmethod
    def _draw_mesh(prog: moderngl.Program, vao: moderngl.VertexArray, model: F32,
                   material: int, color: tuple[float, float, float]) -> None:
        _uniforms(prog, model=model, material=material, base_color=color)
        vao.render()

    # -- read-back (tests, headless) -------------------------------------------------------
    def read_gbuffer(self) -> dict[str, npt.NDArray[np.float32]]:
        """The G-buffer as float arrays (rows bottom to top, as OpenGL stores them): normal,
        linear albedo, material id, depth, and world positions rebuilt from the depth buffer
        as the shaders rebuild them."""
        w, h = self.inner
        depth = np.frombuffer(self.g_depth.read(), dtype=np.float32).reshape(h, w)
        stored = (np.frombuffer(self.g_albedo.read(), dtype=np.uint8)
                  .reshape(h, w, 4).astype(np.float32) / 255.0)
        out = {
            "normal": np.frombuffer(self.g_normal.read(), dtype=np.float16)
            .reshape(h, w, 4).astype(np.float32),
            "albedo": stored[..., :3] ** 2,  # linear; stored as its square root
            "depth": depth,
            "material": np.rint(stored[..., 3] * 255.0),
        }
        u = (np.arange(w, dtype=np.float64) + 0.5) / w * 2.0 - 1.0
        v = (np.arange(h, dtype=np.float64) + 0.5) / h * 2.0 - 1.0
        ndc = np.stack(np.broadcast_arrays(u[None, :], v[:, None], depth * 2.0 - 1.0,
                                           np.ones((h, w))), axis=-1)
        world = ndc @ self._inv_view_proj.astype(np.float64).T
        position = world[..., :3] / world[..., 3:]
        push = np.frombuffer(self.g_normal.read(), dtype=np.float16).reshape(h, w, 4)[..., 3]
        pushed = push > 0.0
        ray = position[pushed] - self._eye
        position[pushed] -= (ray / np.linalg.norm(ray, axis=1, keepdims=True)
                             * push[pushed, None].astype(np.float64))
        out["position"] = position.astype(np.float32)
        return out


class _Slivers:
    """The drawn triangles along cuts whose winding disagrees with some of their vertex
    normals, marked for the cloth's shaders by their provoking (last) vertex: a cut vertex
    (index ``>= first_cut``) where it disagrees, a particle where it agrees.

    Where a stroke passes near a triangle's corner, the quad beyond it is drawn as two
    triangles, one a sliver whose two cut vertices follow two particles' frames; as the
    cloth bends they can cross, and the sliver then stands at any angle to the cloth round it,
    its face saying nothing of which side of the cloth the viewer sees there: its vertex
    normals (its particles') do, taken toward the eye, and a marked triangle shows the side
    they face toward it (geometry.frag). Its winding is kept (each triangle is only turned),
    so the rasteriser draws the same pixels, and a triangle off the cuts is drawn as before."""

    def __init__(self, triangles: npt.NDArray[np.uint32], first_cut: int) -> None:
        self.triangles = triangles.copy()
        cut = triangles >= first_cut
        self.rows = np.flatnonzero(cut.any(axis=1) & ~cut.all(axis=1))
        tris, cut = triangles[self.rows], cut[self.rows]
        # Each row turned to end on a cut vertex, and on a particle.
        self.on_cut = _turned_to_end_on(tris, np.argmax(cut, axis=1))
        self.on_particle = _turned_to_end_on(tris, np.argmin(cut, axis=1))
        self.triangles[self.rows] = self.on_particle
        self.marked = np.zeros(len(self.rows), dtype=bool)

    def mark(self, positions: F32, normals: F32) -> bool:
        """Mark the triangles that disagree with their normals now; True if any changed."""
        if not len(self.rows):
            return False
        tris = self.on_cut
        x = positions[tris]
        face = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        marked = (np.einsum("ij,ikj->ik", face, normals[tris]) <= 0.0).any(axis=1)
        if np.array_equal(marked, self.marked):
            return False
        self.marked = marked
        self.triangles[self.rows] = np.where(marked[:, None], self.on_cut, self.on_particle)
        return True


def _turned_to_end_on(triangles: npt.NDArray[np.uint32],
                      last: npt.NDArray[np.intp]) -> npt.NDArray[np.uint32]:
    """Each triangle's vertices turned (its winding kept) so that column ``last`` ends it."""
    order = (np.arange(3)[None, :] + last[:, None] + 1) % 3
    return np.take_along_axis(triangles, order, axis=1)


def _write_growing(buffer: moderngl.Buffer, data: npt.NDArray[Any]) -> None:
    """Write ``data`` at the start of ``buffer``, giving it new storage first if too small."""
    if data.nbytes > buffer.size:
        buffer.orphan(data.nbytes)
    buffer.write(data)


def _scaled(color: K.RGB, intensity: float) -> tuple[float, float, float]:
    lin = K.srgb_to_linear(color)
    return (lin[0] * intensity, lin[1] * intensity, lin[2] * intensity)


def _uniforms(prog: moderngl.Program, **values: Any) -> None:
    """Set uniforms by name; matrices and arrays are numpy (matrices row-major, as the camera
    makes them). A uniform the compiler optimised away for this program is skipped."""
    for name, value in values.items():
        if name not in prog:
            continue
        uniform = cast(moderngl.Uniform, prog[name])
        if isinstance(value, np.ndarray):
            data = gl_bytes(value) if value.shape == (4, 4) else np.ascontiguousarray(
                value, dtype=np.float32).tobytes()
            uniform.write(data)
        else:
            uniform.value = value


def _bind(prog: moderngl.Program, textures: dict[str, moderngl.Texture]) -> None:
    for unit, (name, tex) in enumerate(textures.items()):
        if name in prog:
            tex.use(unit)
            cast(moderngl.Uniform, prog[name]).value = unit
