"""Garments from flat panels sewn together, on the mannequin or any body of colliders.

A panel is a flat outline in metres (``(u, v)`` points of a simple polygon, optionally with
holes) with named edges, placed in the scene flat or wrapped on a cylinder; a seam joins two
named edges, ``"panel.edge"``. The scene compiles them (``cloth.garment``, src/garment/) into a
mesh cloth: each panel meshed by constrained Delaunay triangulation at ``edge_length``, the
seamed edges sampled at matching points, and seam springs that draw the pairs together over
``sew_time`` and then hold them (docs/garments.md).

>>> from rustcloth import garment
>>> front = garment.panel("front", [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]],
...                       edges={"right": [1, 2]})
>>> back = garment.panel("back", [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]],
...                      edges={"left": [3, 0]}, origin=[0.35, 0, 0])
>>> scene = garment.scene([front, back], [garment.seam("front.right", "back.left")])
>>> mesh = scene.cloth["mesh"]
>>> seams = mesh["seams"]
>>> len(seams["pairs"]), seams["sew_time"]
(11, 1.0)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from .scene import Scene, load_scene

__all__ = ["panel", "scene", "seam", "shirt", "skirt"]

#: The material of the built-in garments: a light cotton, softer in bending than the mesh
#: cloth's default (``density`` kg/m^2, ``stretch``, ``bend`` N/m, ``damping`` N s/m).
COTTON: dict[str, float] = {"density": 0.2, "stretch": 600.0, "bend": 20.0, "damping": 0.07}

#: Stepping of the built-in garments on the mannequin: symplectic Euler at 0.2 ms substeps,
#: within the estimated stability limit (Scene.stability_report, 0.213 ms) with 3 cm
#: triangles and the seams' springs; air drag brings them to rest.
STEPPING: dict[str, Any] = {"integrator": "symplectic_euler", "dt": 0.001, "substeps": 5,
                            "air_drag": 0.0002}

#: Damping of the built-in garments' seams (N s/m per sewn pair): the seam springs at the
#: lightest corner vertices set the stability limit, and 0.05 N s/m took it to 0.192 ms.
SEAM_DAMPING = 0.02

#: Self-collision of the built-in garments: a thickness (m) below half their shortest triangle
#: altitude (11.6 mm), above the gap their seams hold carrying the cloth's tension (2 mm).
SELF_COLLISION: dict[str, Any] = {"thickness": 0.003}


def panel(name: str, outline: Sequence[Sequence[float]], *,
          edges: Mapping[str, Sequence[int]] | None = None,
          holes: Sequence[Sequence[Sequence[float]]] = (),
          origin: Sequence[float] = (0.0, 0.0, 0.0),
          x_axis: Sequence[float] = (1.0, 0.0, 0.0),
          y_axis: Sequence[float] = (0.0, 1.0, 0.0),
          wrap_radius: float | None = None) -> dict[str, Any]:
    """A panel: ``outline`` points ``(u, v)`` in m, ``edges`` named as ``{"side": [start,
    end]}`` (outline points, walking forward), placed at ``origin + u x_axis + v y_axis``, or
    wrapped on a cylinder of ``wrap_radius`` m about ``y_axis`` that runs ``wrap_radius``
    behind ``origin``. Checked when the scene is built."""
    placement: dict[str, Any] = {"origin": list(origin), "x_axis": list(x_axis),
                                 "y_axis": list(y_axis)}
    if wrap_radius is not None:
        placement["wrap_radius"] = wrap_radius
    return {"name": name, "outline": [list(p) for p in outline],
            "holes": [[list(p) for p in hole] for hole in holes],
            "edges": {k: list(v) for k, v in (edges or {}).items()}, "placement": placement}


def seam(a: str, b: str, reverse: bool = False) -> dict[str, Any]:
    """A seam joining the named edges ``a`` and ``b`` (``"panel.edge"``): ``a``'s start to
    ``b``'s end, each outline taken counter-clockwise, as two panels that face the same way
    meet; ``reverse`` sews start to start."""
    return {"a": a, "b": b, "reverse": reverse}


def scene(panels: Sequence[Mapping[str, Any]], seams: Sequence[Mapping[str, Any]] = (), *,
          body: Scene | None = None, edge_length: float = 0.03, sew_time: float = 1.0,
          seam_stiffness: float = 500.0, seam_damping: float = 0.05,
          **material: float | str) -> Scene:
    """The scene of a garment: ``body``'s floor and colliders (default none) and stepping
    (its ``dt``, ``substeps``, ...), with the garment as its cloth. ``material`` is the
    cloth's ``density``, ``stretch``, ``bend``, ``damping``, ``membrane`` (``"springs"`` or
    ``"triangle"``) and ``poisson`` (default the mesh cloth's, docs/mesh_cloth.md)."""
    data = body.to_dict() if body is not None else {}
    data["cloth"] = {"pins": [], "garment": {
        "panels": [dict(p) for p in panels], "seams": [dict(s) for s in seams],
        "edge_length": edge_length, "sew_time": sew_time, "seam_stiffness": seam_stiffness,
        "seam_damping": seam_damping, **material}}
    return Scene.from_dict(data)


def _mannequin() -> Scene:
    return load_scene("mannequin").replace(**STEPPING, self_collision=SELF_COLLISION)


def shirt(edge_length: float = 0.03, sew_time: float = 1.5) -> Scene:
    """A sleeveless shirt on the mannequin (the built-in ``shirt`` scene): front and back lie
    flat above it, joined at the shoulders, a neck opening between them that the head passes
    through; they drape over the shoulders and the side seams under the arms close."""
    # u across the body, v from the shoulder line to the hem; the neck dips 12 cm.
    outline = [[-0.31, 0.0], [-0.14, 0.0], [-0.09, 0.09], [0.0, 0.12], [0.09, 0.09],
               [0.14, 0.0], [0.31, 0.0], [0.31, 0.18], [0.31, 0.62], [-0.31, 0.62],
               [-0.31, 0.18]]
    edges = {"shoulder_a": [0, 1], "shoulder_b": [5, 6], "side_a": [7, 8], "side_b": [9, 10]}
    top = [0.0, 1.85, 0.0]
    panels = [panel("front", outline, edges=edges, origin=top, x_axis=[-1, 0, 0],
                    y_axis=[0, 0, 1]),
              panel("back", outline, edges=edges, origin=top, x_axis=[1, 0, 0],
                    y_axis=[0, 0, -1])]
    seams = [seam("front.shoulder_a", "back.shoulder_b"),
             seam("front.shoulder_b", "back.shoulder_a"),
             seam("front.side_a", "back.side_b"), seam("front.side_b", "back.side_a")]
    return scene(panels, seams, body=_mannequin(), edge_length=edge_length, sew_time=sew_time,
                 seam_damping=SEAM_DAMPING, **COTTON)


def skirt(edge_length: float = 0.03, sew_time: float = 0.2) -> Scene:
    """A straight skirt on the mannequin (the built-in ``skirt`` scene): front and back wrapped
    on a cylinder just outside the torso, its sides apart; the side seams close and the waist,
    cut 7 % smaller round than the torso, grips it."""
    outline = [[-0.26, -0.5], [0.26, -0.5], [0.245, 0.0], [-0.245, 0.0]]
    edges = {"right": [1, 2], "left": [3, 0]}
    r = 0.172
    panels = [panel("front", outline, edges=edges, origin=[0, 1.25, r], wrap_radius=r),
              panel("back", outline, edges=edges, origin=[0, 1.25, -r], x_axis=[-1, 0, 0],
                    wrap_radius=r)]
    seams = [seam("front.right", "back.left"), seam("front.left", "back.right")]
    return scene(panels, seams, body=_mannequin(), edge_length=edge_length, sew_time=sew_time,
                 seam_damping=SEAM_DAMPING, **COTTON)
