"""The deferred renderer: shadow map, G-buffer, lighting (or a debug view), FXAA, highlights."""

from __future__ import annotations

import math
from typing import Any, Protocol

import moderngl
import numpy as np
import numpy.typing as npt

from ..camera import Camera, gl_bytes, look_at, orthographic
from . import meshes
from .shaders import load_program

# Material ids stored in the G-buffer's albedo alpha (must match geometry.frag).
MAT_CLOTH, MAT_CLOTH_BACK, MAT_FLOOR, MAT_SPHERE, MAT_MARKER = 1, 2, 3, 4, 5

VIEWS = (
    "lit", "position", "normal", "albedo", "material", "depth", "shadow map",
    "strain", "speed", "pinned",
)
_CHANNELS = {"position": 1, "normal": 2, "albedo": 3, "material": 4, "depth": 5, "shadow map": 6}
# Colour-map range for the cloth debug views: strain 10% and speed 3 m/s map to red.
_SCALAR_SCALE = {"strain": 10.0, "speed": 1.0 / 3.0, "pinned": 1.0}

# The core winds its triangles so the front faces down on a flat-laid cloth: the red weave
# therefore goes on the back, which is what a draped cloth shows on top.
CLOTH_FRONT = (0.86, 0.80, 0.66)
CLOTH_BACK = (0.62, 0.16, 0.14)
FLOOR_COLOR = (0.36, 0.37, 0.39)
SPHERE_COLOR = (0.35, 0.45, 0.62)
MARKER_COLOR = (1.0, 0.85, 0.1)


class ClothSource(Protocol):
    """What the renderer reads from a :class:`rustcloth.Simulation` (or a stand-in)."""

    nx: int
    ny: int
    num_particles: int
    topology_version: int

    @property
    def positions(self) -> npt.NDArray[np.float32]: ...
    @property
    def normals(self) -> npt.NDArray[np.float32]: ...
    @property
    def triangles(self) -> npt.NDArray[np.uint32]: ...


def scene_of(sim: Any) -> dict[str, Any]:
    return sim.scene.to_dict()


def scene_extent(scene: dict[str, Any]) -> tuple[npt.NDArray[np.float32], float, float]:
    """(cloth centre, cloth size, ground height) where the ground is the floor, or for scenes
    without one a visual ground below the reach of the hanging cloth (not a collider)."""
    cloth = scene["cloth"]
    center = np.asarray(cloth["center"], dtype=np.float32)
    size = float(max(cloth["size"]))
    floor = scene.get("floor")
    ground = float(floor["height"]) if floor else float(center[1] - 1.25 * size - 0.1)
    return center, size, ground


def default_camera(scene: dict[str, Any], aspect: float) -> Camera:
    """A three-quarter view framing the cloth and what it falls onto."""
    center, size, ground = scene_extent(scene)
    target = np.array([center[0], 0.5 * (center[1] + ground), center[2]], dtype=np.float32)
    direction = np.array([0.55, 0.42, 1.0], dtype=np.float32)
    direction /= np.linalg.norm(direction)
    span = max(size, center[1] - ground)
    eye = target + direction * (1.45 * span + 0.2)
    return Camera(eye=eye, target=target, fov=45.0, aspect=aspect, near=0.05, far=60.0)


class Renderer:
    """Draws one simulation into any framebuffer.

    Per frame, :meth:`update` uploads positions and normals into persistent vertex buffers
    with ``buffer.write``; the index buffer is rewritten only when ``topology_version``
    changes. :meth:`render` then runs the passes.
    """

    def __init__(
        self, ctx: moderngl.Context, sim: ClothSource, size: tuple[int, int],
        shadow_size: int = 2048,
    ) -> None:
        self.ctx = ctx
        self.view = "lit"
        self.shadows = True
        self.fxaa = True
        self.ssao = False
        self.highlight: int | None = None
        self.light_dir = np.array([-0.45, -1.0, -0.35], dtype=np.float32)
        self.light_dir /= np.linalg.norm(self.light_dir)
        self.light_color = np.array([1.35, 1.28, 1.15], dtype=np.float32)
        self.ambient = np.array([0.16, 0.17, 0.2], dtype=np.float32)

        self.geometry = load_program(ctx, "geometry.vert", "geometry.frag")
        self.shadow_prog = load_program(ctx, "shadow.vert", "shadow.frag")
        self.lighting = load_program(ctx, "fullscreen.vert", "lighting.frag")
        self.debug = load_program(ctx, "fullscreen.vert", "debug.frag")
        self.fxaa_prog = load_program(ctx, "fullscreen.vert", "fxaa.frag")
        self.ssao_prog = load_program(ctx, "fullscreen.vert", "ssao.frag")
        self.lines = load_program(ctx, "lines.vert", "lines.frag")
        self.overlay_prog = load_program(ctx, "overlay.vert", "overlay.frag")
        # Full-screen passes draw one triangle from gl_VertexID: no vertex buffers.
        self.fullscreen = {
            p: ctx.vertex_array(p, [])
            for p in (self.lighting, self.debug, self.fxaa_prog, self.ssao_prog)
        }

        self.shadow_depth = ctx.depth_texture((shadow_size, shadow_size))
        self.shadow_depth.compare_func = "<="
        # Linear filtering of a compare texture gives a free 2x2 PCF on every tap.
        self.shadow_depth.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.shadow_depth.repeat_x = self.shadow_depth.repeat_y = False
        self.shadow_fbo = ctx.framebuffer(depth_attachment=self.shadow_depth)
        self.shadow_size = shadow_size

        sphere_v, sphere_i = meshes.uv_sphere()
        self.sphere_vbo = ctx.buffer(sphere_v)
        self.sphere_ibo = ctx.buffer(sphere_i)
        self.sphere_vao = self._mesh_vao(self.geometry, self.sphere_vbo, self.sphere_ibo)
        self.sphere_shadow_vao = self._mesh_vao(self.shadow_prog, self.sphere_vbo, self.sphere_ibo)

        self.stroke_vbo = ctx.buffer(reserve=4096 * 12)
        self.stroke_vao = ctx.vertex_array(self.lines, [(self.stroke_vbo, "3f", "in_position")])
        self.stroke_count = 0
        self._stroke_version = -1

        self.overlay_tex: moderngl.Texture | None = None
        self.overlay_vao = ctx.vertex_array(self.overlay_prog, [])

        self.size = (0, 0)
        self.resize(size)
        self.set_simulation(sim)

    # -- set-up ----------------------------------------------------------------------------
    def _mesh_vao(
        self, prog: moderngl.Program, vbo: moderngl.Buffer, ibo: moderngl.Buffer
    ) -> moderngl.VertexArray:
        if "in_normal" in prog:
            fmt = [(vbo, "3f 3f 2f", "in_position", "in_normal", "in_uv")]
        else:
            fmt = [(vbo, "3f 12x 8x", "in_position")]
        return self.ctx.vertex_array(prog, fmt, index_buffer=ibo, index_element_size=4)

    def resize(self, size: tuple[int, int]) -> None:
        """(Re)create the G-buffer and the lit image at the output size."""
        size = (max(1, int(size[0])), max(1, int(size[1])))
        if size == self.size:
            return
        for name in ("gbuffer", "g_position", "g_normal", "g_albedo", "g_depth", "lit_fbo", "lit",
                     "ao_fbo", "ao"):
            old = getattr(self, name, None)
            if old is not None:
                old.release()
        ctx = self.ctx
        self.size = size
        self.g_position = ctx.texture(size, 4, dtype="f4")
        self.g_normal = ctx.texture(size, 4, dtype="f2")
        self.g_albedo = ctx.texture(size, 4, dtype="f1")
        self.g_depth = ctx.depth_texture(size)
        for tex in (self.g_position, self.g_normal, self.g_albedo, self.g_depth):
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.g_depth.compare_func = ""  # read as plain depth by the debug view
        self.gbuffer = ctx.framebuffer(
            color_attachments=[self.g_position, self.g_normal, self.g_albedo],
            depth_attachment=self.g_depth,
        )
        self.lit = ctx.texture(size, 4, dtype="f1")
        self.lit.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.lit.repeat_x = self.lit.repeat_y = False
        self.lit_fbo = ctx.framebuffer(color_attachments=[self.lit])
        self.ao = ctx.texture(size, 1, dtype="f1")
        self.ao.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.ao.repeat_x = self.ao.repeat_y = False
        self.ao_fbo = ctx.framebuffer(color_attachments=[self.ao])

    def set_simulation(self, sim: ClothSource) -> None:
        """Bind a (new) simulation: cloth buffers sized for it and the scene's static meshes."""
        ctx = self.ctx
        for name in ("cloth_pos", "cloth_nrm", "cloth_uv", "cloth_scalar", "cloth_ibo"):
            old = getattr(self, name, None)
            if old is not None:
                old.release()
        self.sim = sim
        n = sim.num_particles
        self.cloth_pos = ctx.buffer(reserve=n * 12, dynamic=True)
        self.cloth_nrm = ctx.buffer(reserve=n * 12, dynamic=True)
        self.cloth_uv = ctx.buffer(meshes.cloth_uv(sim.nx, sim.ny))
        self.cloth_scalar = ctx.buffer(reserve=n * 4, dynamic=True)
        self.cloth_ibo = ctx.buffer(reserve=max(1, sim.triangles.nbytes), dynamic=True)
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
        self._topology = -1
        self.index_count = 0
        self.positions = np.zeros((n, 3), dtype=np.float32)

        scene = scene_of(sim)
        center, size, ground = scene_extent(scene)
        self.grid_size = (float(sim.nx - 1), float(sim.ny - 1))
        self.spacing = size / max(sim.nx - 1, 1)
        old = getattr(self, "floor_vbo", None)
        if old is not None:
            old.release()
        floor_v, floor_i = meshes.floor_quad((float(center[0]), float(center[2])), ground, 6.0)
        self.floor_vbo = ctx.buffer(floor_v)
        self.floor_ibo = ctx.buffer(floor_i)
        self.floor_vao = self._mesh_vao(self.geometry, self.floor_vbo, self.floor_ibo)
        self.sphere_models = [meshes.translate_scale(s["center"], float(s["radius"]))
                              for s in scene.get("spheres", [])]
        # The light's orthographic box covers the cloth's reach and the obstacles under it.
        reach = 1.0 * size + 0.6
        focus = np.array([center[0], 0.5 * (center[1] + ground), center[2]], dtype=np.float32)
        light_eye = focus - self.light_dir * (4.0 * reach)
        up = (0.0, 0.0, 1.0) if abs(self.light_dir[1]) > 0.99 else (0.0, 1.0, 0.0)
        self.light_view_proj = (
            orthographic(reach, reach, 0.1, 8.0 * reach) @ look_at(light_eye, focus, up)
        ).astype(np.float32)
        self.focus = focus
        self.scene_size = size
        self.point_pos, self.point_color = self._point_lights(focus, size)
        self.update()

    @staticmethod
    def _point_lights(
        focus: npt.NDArray[np.float32], size: float
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Eight fill lights on a ring, alternating warm and cool, for soft coloured rims."""
        k = np.arange(8, dtype=np.float32)
        ang = k * (2.0 * math.pi / 8.0) + 0.3
        radius = 1.6 * size + 0.5
        pos = np.column_stack([
            focus[0] + radius * np.cos(ang),
            focus[1] + 0.4 * size + 0.5 + 0.25 * (k % 2),
            focus[2] + radius * np.sin(ang),
        ]).astype(np.float32)
        warm = np.array([0.30, 0.22, 0.15], dtype=np.float32)
        cool = np.array([0.13, 0.19, 0.30], dtype=np.float32)
        color = np.where((k % 2 == 0)[:, None], warm, cool).astype(np.float32)
        return pos, color

    # -- per frame -------------------------------------------------------------------------
    def update(self) -> None:
        """Upload the simulation's current state (the one per-frame position upload)."""
        sim = self.sim
        self.positions = sim.positions
        self.cloth_pos.write(self.positions)
        self.cloth_nrm.write(sim.normals)
        if sim.topology_version != self._topology:
            tris = sim.triangles
            if tris.nbytes > self.cloth_ibo.size:
                self.cloth_ibo.orphan(tris.nbytes)
            self.cloth_ibo.write(tris)
            self.index_count = tris.size
            self._topology = sim.topology_version
        if self.view in _SCALAR_SCALE:
            self.cloth_scalar.write(self._scalar(self.view))

    def invalidate_topology(self) -> None:
        """Force an index upload next frame: ``reset()`` sets ``topology_version`` back to 0,
        so a reset followed by a cut within one frame could repeat the cached version."""
        self._topology = -1

    def _scalar(self, view: str) -> npt.NDArray[np.float32]:
        sim: Any = self.sim
        if view == "strain":
            return np.ascontiguousarray(sim.spring_strain(), dtype=np.float32)
        if view == "speed":
            return np.linalg.norm(sim.velocities, axis=1).astype(np.float32)
        return np.asarray(sim.pinned, dtype=np.float32)

    def sync_stroke(self, source: Any) -> None:
        """Upload the cut stroke of ``source`` (an :class:`Interaction`: ``stroke_version`` and
        ``stroke()`` giving world-space segments (M*2, 3)) only when it changed, so a frame
        without cutting allocates nothing here."""
        if source.stroke_version == self._stroke_version:
            return
        self._stroke_version = source.stroke_version
        data = np.ascontiguousarray(source.stroke(), dtype=np.float32).reshape(-1, 3)
        if data.nbytes > self.stroke_vbo.size:
            self.stroke_vbo.orphan(2 * data.nbytes)
        if data.size:
            self.stroke_vbo.write(data)
        self.stroke_count = len(data) - len(data) % 2

    def set_overlay(self, image: npt.NDArray[np.uint8] | None) -> None:
        """An RGBA8 text panel (rows top to bottom) drawn at the top-left, or None."""
        if image is None:
            self.overlay_tex = None
            return
        h, w = image.shape[:2]
        if self.overlay_tex is None or self.overlay_tex.size != (w, h):
            if self.overlay_tex is not None:
                self.overlay_tex.release()
            self.overlay_tex = self.ctx.texture((w, h), 4, dtype="f1")
        self.overlay_tex.write(np.ascontiguousarray(image))

    def render(self, target: moderngl.Framebuffer, camera: Camera) -> None:
        ctx = self.ctx
        w, h = self.size
        view_proj = gl_bytes(camera.view_projection)
        identity = gl_bytes(np.identity(4, dtype=np.float32))
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)

        # Shadow pass: depth from the key light; cloth is drawn double-sided so it shadows
        # itself, and slope-scaled polygon offset keeps the receivers free of acne.
        self.shadow_fbo.use()
        self.shadow_fbo.clear(depth=1.0)
        if self.shadows:
            ctx.polygon_offset = (1.5, 2.0)
            self.shadow_prog["light_view_proj"].write(gl_bytes(self.light_view_proj))
            self.shadow_prog["model"].write(identity)
            if self.index_count:
                self.cloth_shadow_vao.render(vertices=self.index_count)
            for model in self.sphere_models:
                self.shadow_prog["model"].write(gl_bytes(model))
                self.sphere_shadow_vao.render()
            ctx.polygon_offset = (0.0, 0.0)

        # Geometry pass: every surface into the G-buffer (position, normal, albedo + id, depth).
        self.gbuffer.use()
        self.gbuffer.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        g = self.geometry
        g["view_proj"].write(view_proj)
        g["cloth_mode"].value = 1 if self.view in _SCALAR_SCALE else 0
        g["scalar_scale"].value = _SCALAR_SCALE.get(self.view, 1.0)
        g["grid_size"].value = self.grid_size
        g["back_color"].value = CLOTH_BACK
        self._draw_geometry(g, self.floor_vao, identity, MAT_FLOOR, FLOOR_COLOR)
        for model in self.sphere_models:
            self._draw_geometry(g, self.sphere_vao, gl_bytes(model), MAT_SPHERE, SPHERE_COLOR)
        if self.index_count:
            g["model"].write(identity)
            g["material"].value = MAT_CLOTH
            g["base_color"].value = CLOTH_FRONT
            self.cloth_vao.render(vertices=self.index_count)
        if self.highlight is not None and 0 <= self.highlight < len(self.positions):
            model = meshes.translate_scale(self.positions[self.highlight], 0.9 * self.spacing)
            self._draw_geometry(g, self.sphere_vao, gl_bytes(model), MAT_MARKER, MARKER_COLOR)

        ctx.disable(moderngl.DEPTH_TEST)
        if self.ssao and self.view == "lit":
            # SSAO pass: occlusion of the ambient and fill light from the G-buffer.
            self.ao_fbo.use()
            a = self.ssao_prog
            self._bind(a, {"g_position": self.g_position, "g_normal": self.g_normal,
                           "g_albedo": self.g_albedo})
            a["view_proj"].write(view_proj)
            a["eye"].value = tuple(camera.eye)
            a["radius"].value = 0.15 * self.scene_size
            self.fullscreen[a].render(moderngl.TRIANGLES, vertices=3)
        self.lit_fbo.use()
        if self.view in _CHANNELS:
            # Debug pass: one raw G-buffer channel instead of lighting.
            d = self.debug
            self._bind(d, {"g_position": self.g_position, "g_normal": self.g_normal,
                           "g_albedo": self.g_albedo, "g_depth": self.g_depth,
                           "shadow_depth": self.shadow_depth})
            self.shadow_depth.compare_func = ""
            d["channel"].value = _CHANNELS[self.view]
            d["near"].value, d["far"].value = camera.near, camera.far
            self.fullscreen[d].render(moderngl.TRIANGLES, vertices=3)
            self.shadow_depth.compare_func = "<="
        else:
            # Lighting pass: key light with PCF shadows, eight point lights, ambient.
            lp = self.lighting
            self._bind(lp, {"g_position": self.g_position, "g_normal": self.g_normal,
                            "g_albedo": self.g_albedo, "shadow_map": self.shadow_depth,
                            "ao_map": self.ao})
            lp["ao_enabled"].value = self.ssao
            lp["light_view_proj"].write(gl_bytes(self.light_view_proj))
            lp["light_dir"].value = tuple(self.light_dir)
            lp["light_color"].value = tuple(self.light_color)
            lp["shadows_enabled"].value = self.shadows
            lp["shadow_texel"].value = 1.0 / self.shadow_size
            lp["eye"].value = tuple(camera.eye)
            lp["ambient"].value = tuple(self.ambient)
            lp["point_pos"].write(self.point_pos.tobytes())
            lp["point_color"].write(self.point_color.tobytes())
            lp["point_radius"].value = 4.0 * self.scene_size + 2.0
            lp["sky_top"].value = (0.32, 0.42, 0.56)
            lp["sky_bottom"].value = (0.78, 0.80, 0.82)
            self.fullscreen[lp].render(moderngl.TRIANGLES, vertices=3)

        # FXAA pass: anti-alias the tonemapped image into the caller's framebuffer.
        target.use()
        ctx.viewport = (0, 0, w, h)
        f = self.fxaa_prog
        self._bind(f, {"image": self.lit})
        f["texel"].value = (1.0 / w, 1.0 / h)
        f["enabled"].value = self.fxaa and self.view == "lit"
        self.fullscreen[f].render(moderngl.TRIANGLES, vertices=3)

        # Highlight pass: the cut stroke on top of everything, so it stays visible behind folds.
        if self.stroke_count:
            self.lines["view_proj"].write(view_proj)
            self.lines["color"].value = (1.0, 0.9, 0.15, 1.0)
            self.stroke_vao.render(moderngl.LINES, vertices=self.stroke_count)
        if self.overlay_tex is not None:
            # Overlay pass: the text panel, alpha-blended at the top-left.
            ow, oh = self.overlay_tex.size
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            self.overlay_tex.use(0)
            self.overlay_prog["text"].value = 0
            x1, y0 = -1.0 + 2.0 * ow / w, 1.0 - 2.0 * oh / h
            self.overlay_prog["rect"].value = (-1.0, y0, x1, 1.0)
            self.overlay_vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
            ctx.disable(moderngl.BLEND)

    def _draw_geometry(
        self, g: moderngl.Program, vao: moderngl.VertexArray, model: bytes, material: int,
        color: tuple[float, float, float],
    ) -> None:
        g["model"].write(model)
        g["material"].value = material
        g["base_color"].value = color
        vao.render()

    @staticmethod
    def _bind(prog: moderngl.Program, textures: dict[str, moderngl.Texture]) -> None:
        for unit, (name, tex) in enumerate(textures.items()):
            if name in prog:
                tex.use(unit)
                prog[name].value = unit

    # -- read-back (tests, headless) -------------------------------------------------------
    def read_gbuffer(self) -> dict[str, npt.NDArray[np.float32]]:
        """The G-buffer as float arrays (rows bottom to top, as OpenGL stores them)."""
        w, h = self.size
        out = {
            "position": np.frombuffer(self.g_position.read(), dtype=np.float32).reshape(h, w, 4),
            "normal": np.frombuffer(self.g_normal.read(), dtype=np.float16)
            .reshape(h, w, 4).astype(np.float32),
            "albedo": np.frombuffer(self.g_albedo.read(), dtype=np.uint8)
            .reshape(h, w, 4).astype(np.float32) / 255.0,
            "depth": np.frombuffer(self.g_depth.read(), dtype=np.float32).reshape(h, w),
        }
        out["material"] = np.rint(out["albedo"][..., 3] * 255.0)
        return out
