"""A look-at perspective camera: matrices for OpenGL and rays from window pixels.

Matrices are numpy float32 in the usual maths convention (``clip = P @ V @ world`` with column
vectors); :func:`gl_bytes` transposes them into the column-major bytes GLSL expects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

Vec3 = npt.NDArray[np.float32]
Mat4 = npt.NDArray[np.float32]


def _vec(v: npt.ArrayLike) -> Vec3:
    return np.asarray(v, dtype=np.float32).reshape(3)


def _unit(v: npt.NDArray[np.floating]) -> Vec3:
    n = float(np.linalg.norm(v))
    if n == 0.0 or not math.isfinite(n):
        raise ValueError(f"cannot normalise vector {v!r}")
    return (v / n).astype(np.float32)


def gl_bytes(m: npt.NDArray[np.floating]) -> bytes:
    """Column-major float32 bytes of a row-major numpy matrix, ready for ``uniform.write``."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()


def look_at(eye: npt.ArrayLike, target: npt.ArrayLike, up: npt.ArrayLike) -> Mat4:
    e, t, u = _vec(eye), _vec(target), _vec(up)
    f = _unit(t - e)
    s = _unit(np.cross(f, u))
    u2 = np.cross(s, f)
    m = np.identity(4, dtype=np.float32)
    m[0, :3], m[1, :3], m[2, :3] = s, u2, -f
    m[:3, 3] = -m[:3, :3] @ e
    return m


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> Mat4:
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4), dtype=np.float32)
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def fit_distance(points: npt.ArrayLike, target: npt.ArrayLike, direction: npt.ArrayLike,
                 fov_y_deg: float, aspect: float, margin: float = 0.9) -> float:
    """How far from ``target`` along ``direction`` (unit, from the target towards the eye) a
    camera looking at ``target`` must stand for every point to project inside ``margin`` of
    the half-width and half-height of its view (0 < margin <= 1)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    forward = -np.asarray(direction, dtype=np.float64).reshape(3)
    right = np.cross(forward, (0.0, 1.0, 0.0))
    if float(np.linalg.norm(right)) < 1e-6:
        right = np.cross(forward, (0.0, 0.0, -1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = pts - np.asarray(target, dtype=np.float64).reshape(3)
    x, y, z = np.abs(rel @ right), np.abs(rel @ up), rel @ forward
    ty = math.tan(math.radians(fov_y_deg) / 2.0) * margin
    tx = ty * aspect
    # |x| / (d + z) <= tx and |y| / (d + z) <= ty for every point, all in front of the eye.
    need = np.maximum(x / tx, y / ty) - z
    return float(max(need.max(), 0.2 - z.min(), 0.1))


def orthographic(left: float, right: float, bottom: float, top: float, near: float,
                 far: float) -> Mat4:
    """The box ``[left, right] x [bottom, top]`` between ``near`` and ``far`` (distances in
    front of the eye, which looks along -z) mapped onto OpenGL's clip cube."""
    m = np.identity(4, dtype=np.float32)
    m[0, 0] = 2.0 / (right - left)
    m[1, 1] = 2.0 / (top - bottom)
    m[2, 2] = -2.0 / (far - near)
    m[0, 3] = -(right + left) / (right - left)
    m[1, 3] = -(top + bottom) / (top - bottom)
    m[2, 3] = -(far + near) / (far - near)
    return m


def light_view_projection(direction: npt.ArrayLike, points: npt.ArrayLike) -> Mat4:
    """An orthographic view along ``direction`` (the way the light travels) whose box just
    holds ``points``: the key light's shadow-map matrix, as tight as the scene allows."""
    d = _unit(_vec(direction))
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    center = pts.mean(axis=0)
    radius = float(np.linalg.norm(pts - center, axis=1).max()) + 1e-3
    up = (0.0, 0.0, 1.0) if abs(float(d[1])) > 0.99 else (0.0, 1.0, 0.0)
    view = look_at(center - d * (2.0 * radius), center, up)
    local = pts @ view[:3, :3].T + view[:3, 3]
    lo, hi = local.min(axis=0), local.max(axis=0)
    # The eye looks along -z: distances in front of it are -z.
    proj = orthographic(float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]),
                        float(-hi[2]) - 0.05, float(-lo[2]) + 0.05)
    return (proj @ view).astype(np.float32)


@dataclass
class Camera:
    """Perspective camera orbiting ``target``.

    ``fov`` is the vertical field of view in degrees; ``aspect`` is width / height.
    """

    eye: Vec3 = field(default_factory=lambda: _vec((0.0, 1.0, 3.0)))
    target: Vec3 = field(default_factory=lambda: _vec((0.0, 0.5, 0.0)))
    up: Vec3 = field(default_factory=lambda: _vec((0.0, 1.0, 0.0)))
    fov: float = 45.0
    aspect: float = 4.0 / 3.0
    near: float = 0.05
    far: float = 50.0

    def __post_init__(self) -> None:
        self.eye, self.target, self.up = _vec(self.eye), _vec(self.target), _vec(self.up)

    # -- matrices --------------------------------------------------------------------------
    @property
    def forward(self) -> Vec3:
        return _unit(self.target - self.eye)

    @property
    def view(self) -> Mat4:
        return look_at(self.eye, self.target, self.up)

    @property
    def projection(self) -> Mat4:
        return perspective(self.fov, self.aspect, self.near, self.far)

    @property
    def view_projection(self) -> Mat4:
        return (self.projection @ self.view).astype(np.float32)

    # -- pixels <-> world ------------------------------------------------------------------
    def ray(self, px: float, py: float, width: int, height: int) -> tuple[Vec3, Vec3]:
        """Ray through window pixel coordinates (origin top-left, continuous: the centre of the
        window is ``(width / 2, height / 2)``), as ``(origin, unit direction)``.

        The origin is the eye; the direction comes from unprojecting the pixel's far-plane point
        through the inverse view-projection, so it agrees with what is drawn.
        """
        ndc_x = 2.0 * px / width - 1.0
        ndc_y = 1.0 - 2.0 * py / height
        inv = np.linalg.inv(self.view_projection.astype(np.float64))
        far = inv @ np.array([ndc_x, ndc_y, 1.0, 1.0])
        near = inv @ np.array([ndc_x, ndc_y, -1.0, 1.0])
        direction = _unit(far[:3] / far[3] - near[:3] / near[3])
        return self.eye.copy(), direction

    def project(self, point: npt.ArrayLike, width: int, height: int) -> tuple[float, float, float]:
        """World point to ``(px, py, ndc_depth)`` in the same pixel convention as :meth:`ray`."""
        clip = self.view_projection.astype(np.float64) @ np.append(_vec(point), 1.0)
        ndc = clip[:3] / clip[3]
        return ((ndc[0] + 1.0) * 0.5 * width, (1.0 - ndc[1]) * 0.5 * height, float(ndc[2]))

    def drag_plane_point(self, ray: tuple[Vec3, Vec3], point: npt.ArrayLike) -> Vec3:
        """Where ``ray`` meets the plane through ``point`` facing the camera (normal = forward),
        so a dragged particle stays at the depth it was grabbed at."""
        origin, direction = _vec(ray[0]), _vec(ray[1])
        p, n = _vec(point), self.forward
        denom = float(direction @ n)
        if abs(denom) < 1e-8:
            return p
        t = float((p - origin) @ n) / denom
        return (origin + t * direction).astype(np.float32)

    # -- navigation ------------------------------------------------------------------------
    def orbit(self, dyaw: float, dpitch: float) -> None:
        """Rotate the eye about the target by angles in radians; pitch stays short of the poles
        so the look-at basis never degenerates."""
        offset = (self.eye - self.target).astype(np.float64)
        r = float(np.linalg.norm(offset))
        yaw = math.atan2(offset[0], offset[2]) + dyaw
        pitch = math.asin(max(-1.0, min(1.0, offset[1] / r))) + dpitch
        pitch = max(-math.radians(89.0), min(math.radians(89.0), pitch))
        self.eye = self.target + _vec((
            r * math.cos(pitch) * math.sin(yaw),
            r * math.sin(pitch),
            r * math.cos(pitch) * math.cos(yaw),
        ))

    def zoom(self, factor: float) -> None:
        """Scale the eye's distance to the target (factor < 1 moves closer)."""
        if not factor > 0.0:
            raise ValueError(f"zoom factor must be positive, got {factor!r}")
        offset = self.eye - self.target
        r = float(np.linalg.norm(offset))
        new_r = min(max(r * factor, 2.0 * self.near), 0.5 * self.far)
        self.eye = (self.target + offset * (new_r / r)).astype(np.float32)
