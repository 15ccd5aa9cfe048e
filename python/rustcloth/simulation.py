"""The public :class:`Simulation`: a documented, typed wrapper around the Rust solver.

It wraps ``rustcloth._core.Simulation`` (it does not subclass it), so its surface is chosen
here: every member has its units, shapes, dtypes and errors below, and the compiled class stays
an implementation detail.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, TypeAlias, cast

import numpy as np
import numpy.typing as npt

from . import _args, _core
from .errors import ParameterError, ParameterTypeError, StabilityWarning
from .mesh import Mesh
from .scene import Scene, load_scene
from .settings import IntegratorName, SelfCollisionSettings

if TYPE_CHECKING:
    from pathlib import Path

PickStrategyName: TypeAlias = Literal["auto", "bvh", "scan"]
"""How ray queries find what they hit; all three give the same answers."""

Vector: TypeAlias = Sequence[float] | npt.NDArray[np.floating[Any]]
"""Three numbers: a list, a tuple or a numpy array (m, or a direction)."""

FloatArray: TypeAlias = npt.NDArray[np.float32]


class Energy(NamedTuple):
    """Energies of the cloth in J."""

    kinetic: float
    """``sum m v^2 / 2`` over live particles."""
    gravitational: float
    """``-sum m g . x``: zero at the origin."""
    elastic: float
    """``sum k (l - L)^2 / 2`` over live springs of the active families."""

    @property
    def total(self) -> float:
        """Kinetic + gravitational + elastic, in J."""
        return self.kinetic + self.gravitational + self.elastic


class RenderMesh(NamedTuple):
    """The drawn surface (:meth:`Simulation.render_mesh`): ``V`` vertices, the particles first,
    then the cut vertices along severed edges; ``T`` triangles."""

    positions: FloatArray
    """``(V, 3)`` float32 in m."""
    triangles: npt.NDArray[np.uint32]
    """``(T, 3)`` uint32 vertex indices."""
    normals: FloatArray
    """``(V, 3)`` float32 unit vertex normals."""
    uvs: FloatArray
    """``(V, 2)`` float32 texture coordinates."""
    sources: npt.NDArray[np.uint32]
    """``(V,)`` uint32: the particle whose values each vertex shows."""


@dataclass(frozen=True)
class PassTime:
    """Time spent in one pass of the step."""

    name: str
    seconds: float
    """Wall time spent in the pass so far."""
    calls: int
    """How many times it ran (force terms once per force evaluation)."""


@dataclass(frozen=True)
class Profile:
    """Where the stepping time went, pass by pass (wall clock, since start or reset)."""

    passes: dict[str, PassTime] = field(default_factory=dict)
    steps: int = 0
    total_seconds: float = 0.0
    solver: dict[str, float] | None = None
    """For the implicit integrators (see :meth:`Simulation.solver_stats`): ``solves``,
    ``iterations`` (total), ``last_iterations``, ``most_iterations``, ``last_residual`` and
    ``worst_residual`` (relative), ``not_converged`` (solves that missed the tolerance),
    ``factorizations``, ``setup_seconds`` and ``solve_seconds``, and ``halved``: solves
    holding contacts that gained energy while nothing did work on the cloth, run again in
    halves (README, "Contact at long steps"); ``self_pairs``: self-collision pairs
    ``implicit_euler`` held apart inside its solves (``self_collision.solve_stiffness``,
    docs/contact.md). For ``implicit_euler`` a solve
    is one conjugate-gradient solve and its residual ``|r| / |b|``; for
    ``projective_dynamics`` a solve is one substep's local-global iterations and its residual
    the relative gradient ``|g_k| / |g_0|``. None for the explicit integrators."""
    integrator: str = ""
    """The integrator the steps ran with (when profiled), naming the solver line of ``str``."""

    def per_step_ms(self) -> dict[str, float]:
        """Milliseconds per step spent in each pass."""
        n = max(self.steps, 1)
        return {name: 1e3 * p.seconds / n for name, p in self.passes.items()}

    def __str__(self) -> str:
        n = max(self.steps, 1)
        lines = [f"{self.steps} steps, {1e3 * self.total_seconds / n:.4f} ms/step"]
        for name, p in self.passes.items():
            share = p.seconds / self.total_seconds if self.total_seconds else 0.0
            lines.append(f"  {name:<20} {1e3 * p.seconds / n:9.4f} ms/step  {share:6.1%}")
        if self.solver:
            s = self.solver
            mean = s["iterations"] / max(s["solves"], 1)
            method = "local-global" if self.integrator == "projective_dynamics" else "CG"
            lines.append(
                f"  {method}: {mean:.1f} iterations/solve, last residual "
                f"{s['last_residual']:.1e}, {s['not_converged']} of {s['solves']} solves "
                "did not converge"
            )
        return "\n".join(lines)


def _as_scene(scene: Scene | Mapping[str, Any] | str | None) -> Scene:
    if scene is None:
        return Scene()
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, str | os.PathLike):
        return load_scene(scene)
    if isinstance(scene, Mapping):
        return Scene.from_dict(scene)
    raise ParameterTypeError(
        f"scene: must be a Scene, a dict, a built-in scene name or a TOML path, got "
        f"{type(scene).__name__}",
        "scene",
    )


def _array(values: npt.ArrayLike, parameter: str) -> np.ndarray:
    """``values`` as a numpy array; ragged nesting (which numpy refuses with its own
    ``ValueError``) is named as ``parameter``."""
    try:
        return np.asarray(values)
    except ValueError as err:
        raise ParameterError(f"{parameter}: must be a rectangular array: {err}",
                             parameter) from None


def _as_state(state: Mapping[str, Any]) -> dict[str, Any]:
    if not isinstance(state, Mapping):
        raise ParameterTypeError(
            f"state: must be a dict from Simulation.get_state(), got {type(state).__name__}",
            "state",
        )
    state = dict(state)
    if "version" in state:
        _args.count(state["version"], "state.version")
    return state


def _ray(origin: object, direction: object) -> tuple[_args.Vec, _args.Vec]:
    return _args.floats(origin, "origin", 3), _args.direction(direction, "direction")


class Simulation:
    """A running cloth simulation.

    ``Simulation(scene)`` takes a :class:`Scene`, a scene dict, or the name of a built-in scene
    (or a TOML path). The state is exposed as ``(N, 3)`` float32 numpy arrays, particle
    ``(i, j)`` at row ``j * nx + i``; reads are read-only copies, writes go through the
    ``set_*`` methods. Stepping runs in parallel in Rust without the GIL and stops at a step
    boundary on Ctrl-C.

    Every bad argument raises a :class:`~rustcloth.errors.RustclothError` subclass that names
    the parameter and leaves the simulation exactly as it was.

    **Threads.** A simulation may be shared by threads. Calls take turns: a call made while
    another thread's call runs waits for it (without holding the GIL) and then sees the state
    at that call's end; the lock is fair, so a thread stepping in a loop cannot starve a reader.
    A long call holds others back for its length: step in pieces (``advance`` per frame) when
    another thread must stay responsive. A call from the thread that is already inside a call
    (a signal handler during ``step``) raises :class:`~rustcloth.errors.SimulationBusy`.

    **Copies.** ``pickle``, ``copy.copy`` and ``copy.deepcopy`` give an independent simulation
    that continues bit for bit (:meth:`get_state`).

    >>> sim = Simulation("hanging")
    >>> sim.step(10)
    >>> sim.positions.shape
    (1024, 3)
    """

    __slots__ = ("_core", "_scene")

    def __init__(self, scene: Scene | Mapping[str, Any] | str | None = None) -> None:
        resolved = _as_scene(scene)
        # The core only reads the dict: no copy of it (a big mesh's arrays are shared).
        self._core = _core.Simulation(resolved._data)
        self._scene: Scene | None = resolved
        limit = self.stable_dt()
        if limit is not None and self.dt > limit:
            warnings.warn(
                f"dt = {self.dt:g} s exceeds the estimated stability limit of {limit:.3g} s for "
                f"{self.integrator} with {self.substeps} substep(s); use a smaller dt, more "
                f"substeps, softer springs or implicit_euler",
                StabilityWarning,
                stacklevel=2,
            )

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Simulation:
        """A simulation continuing ``state`` (from :meth:`get_state`) bit for bit."""
        sim = cls.__new__(cls)
        sim._core = _core.simulation_from_state(_as_state(state))
        sim._scene = None
        return sim

    # ----- stepping ------------------------------------------------------------------------

    def step(self, n: int = 1) -> None:
        """Advance exactly ``n`` steps of ``dt`` (``n`` an integer ``>= 0``).

        Raises :class:`~rustcloth.errors.SimulationDiverged` if a step goes wrong (a non-finite
        value, or a spring beyond the scene's ``watchdog.max_stretch``) and is not saved by a
        retry (``watchdog.on_trouble = "substep"``); the state from before that step is kept.
        Ctrl-C raises ``KeyboardInterrupt`` with the state at the last step boundary.
        """
        self._core.step(_args.count(n, "n"))

    def advance(self, seconds: float) -> int:
        """Add ``seconds`` (s, finite, ``>= 0``) of requested time and run the whole steps of
        ``dt`` it covers, carrying the remainder to the next call; returns the steps taken.

        The result depends only on the total time requested, not on how it is split into calls:
        one second in sixty calls or in one gives the bitwise same state. After a failed step the
        time not simulated stays owed; after Ctrl-C the rest of the call's request is dropped.
        At most 2**32 - 1 steps per call.
        """
        return self._core.advance(_args.real(seconds, "seconds"))

    # ----- state ---------------------------------------------------------------------------

    @property
    def positions(self) -> FloatArray:
        """Positions in m, ``(N, 3)`` float32, row ``j * nx + i``: a read-only copy."""
        return self._core.positions

    @property
    def velocities(self) -> FloatArray:
        """Velocities in m/s, ``(N, 3)`` float32: a read-only copy."""
        return self._core.velocities

    def set_positions(self, positions: npt.NDArray[np.floating[Any]]) -> None:
        """Replace every position (m): an ``(N, 3)`` float32 or float64 array of finite values.
        Integrators with history (Verlet) start afresh."""
        self._core.set_positions(self._rows(positions, "positions", 3))

    def set_velocities(self, velocities: npt.NDArray[np.floating[Any]]) -> None:
        """Replace every velocity (m/s), ``(N, 3)`` float32 or float64, finite. Pinned and cut
        particles keep zero velocity."""
        self._core.set_velocities(self._rows(velocities, "velocities", 3))

    def set_masses(self, masses: npt.NDArray[np.floating[Any]]) -> None:
        """Replace every particle's mass: ``(N,)`` float32 or float64, each in kg, finite,
        ``> 0`` and with a finite float32 inverse."""
        self._core.set_masses(self._rows(masses, "masses"))

    @property
    def masses(self) -> FloatArray:
        """Particle masses in kg, ``(N,)`` float32 (kept for pinned and cut particles)."""
        return self._core.masses

    @property
    def pinned(self) -> npt.NDArray[np.bool_]:
        """``(N,)`` bool: which particles are pinned (kinematic pins included)."""
        return self._core.pinned

    @property
    def alive(self) -> npt.NDArray[np.bool_]:
        """``(N,)`` bool: False for particles that were cut."""
        return self._core.alive

    @property
    def triangles(self) -> npt.NDArray[np.uint32]:
        """``(T, 3)`` uint32 particle indices of the physics surface (what self-collision keeps
        apart): two triangles per grid cell, wound so that a flat cloth's normal is
        ``e_i x e_j``, less those a cut or a tear runs through. Recomputed only after a cut.
        What is drawn and exported follows the cut more closely: :meth:`render_mesh`."""
        return self._core.triangles

    @property
    def normals(self) -> FloatArray:
        """``(N, 3)`` float32 unit vertex normals (area-weighted over live triangles)."""
        return self._core.normals

    def render_positions(self) -> tuple[FloatArray, FloatArray]:
        """The drawn mesh's ``(positions, normals)``, ``(V, 3)`` float32 each: the ``N``
        particles first (as :attr:`positions` and :attr:`normals`), then the cut vertices,
        which put the edge of a severed stroke or a tear where it crossed the springs (see
        docs/cutting.md). ``V`` changes only with :attr:`topology_version`."""
        return self._core.render_positions()

    def render_topology(
        self,
    ) -> tuple[npt.NDArray[np.uint32], FloatArray, npt.NDArray[np.uint32]]:
        """What of the drawn mesh changes only with :attr:`topology_version`: ``triangles``
        ``(T, 3)`` uint32 into the vertices of :meth:`render_positions` (the grid's triangles,
        those a cut crosses clipped along it, the two sides of a cut sharing no vertex);
        ``uvs`` ``(V, 2)`` float32 (particle ``(i, j)`` at ``(i / (nx - 1), j / (ny - 1))``,
        a cut vertex where its edge was crossed); ``sources`` ``(V,)`` uint32, the particle
        whose values (strain, speed) each vertex shows."""
        return self._core.render_topology()

    def render_mesh(self) -> RenderMesh:
        """The drawn mesh now: :meth:`render_positions` and :meth:`render_topology` in one
        :class:`RenderMesh`. A renderer calls the two apart, the topology only when
        :attr:`topology_version` moved."""
        positions, normals = self.render_positions()
        triangles, uvs, sources = self.render_topology()
        return RenderMesh(positions, triangles, normals, uvs, sources)

    @property
    def topology_version(self) -> int:
        """Increments whenever the cloth's springs or particles change, and with them the
        triangle list (a cut, a severed stroke, a tear): caches compare it."""
        return self._core.topology_version

    @property
    def state_version(self) -> int:
        """Increments whenever positions change (a step, ``set_positions``, a reset)."""
        return self._core.state_version

    def pin(self, index: int, target: Vector | None = None) -> None:
        """Pin particle ``index``: it stops and integration no longer moves it. With a
        ``target`` (m) it is a kinematic pin: each step puts it on the target with the velocity
        of that move. Raises :class:`~rustcloth.errors.ParticleIndexError` out of range and
        :class:`~rustcloth.errors.ParameterError` for a cut particle or a non-finite target."""
        index = _args.index(index, "index")
        self._core.pin(index, None if target is None else _args.floats(target, "target", 3))

    def pin_many(self, indices: npt.ArrayLike, targets: npt.ArrayLike | None = None) -> None:
        """Pin every particle of ``indices`` (1-D, integers) as :meth:`pin` pins one, at
        ``targets[k]`` (m, an ``(len(indices), 3)`` array) for ``indices[k]`` when given: one
        call for a whole edge moved every step (a driver such as
        :class:`~rustcloth.drivers.TwistDriver`) instead of one per particle. Every index and
        target is checked first, and a bad one, named ``indices[k]`` or ``targets[k]``, pins
        nothing. A repeated index takes its last target."""
        rows = None if targets is None else _array(targets, "targets")
        ids = _args.indices(_array(indices, "indices"), self.num_particles)
        if rows is not None:
            rows = _args.rows(rows, "targets", (len(ids), 3))
        self._core.pin_many(ids, rows)

    def unpin(self, index: int) -> None:
        """Release particle ``index``; it keeps its velocity. Does nothing if not pinned."""
        self._core.unpin(_args.index(index, "index"))

    def cut(self, index: int) -> None:
        """Remove particle ``index``, every spring touching it, the bending springs over it and
        its triangles (the seed's cutting operation: the mesh loses a whole particle). A cut
        particle is absent from every computation. Cutting twice does nothing."""
        self._core.cut(_args.index(index, "index"))

    def get_state(self) -> dict[str, Any]:
        """The whole state as a dict of numpy arrays and plain values: scene, positions,
        velocities, masses, pins and targets, cuts, step count and clock, the ``advance``
        remainder, the integrator's history, the watchdog's memory and the picking settings;
        a mesh cloth's severed springs as ``mesh_springs`` (a bool per spring, empty on the
        grid).
        :meth:`set_state` or :meth:`from_state` continue it bit for bit; it pickles.
        A mesh cloth's implicit Euler reuses earlier solves' work (coarse operators, CG's
        start) that the state does not hold, so the run that takes it drops that work at its
        next step too, to go on exactly as the restored one: its result after this call can
        differ, within CG's tolerance, from the same run never asked for its state."""
        return self._core.get_state()

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Replace the whole simulation (its scene included) by ``state`` from
        :meth:`get_state`. Every part is checked; a bad one raises naming it
        (``state.positions``, ...), changing nothing."""
        self._core.set_state(_as_state(state))
        self._scene = None

    def reset(self) -> None:
        """Back to the scene's starting state, keeping the run-time integrator, dt and
        substeps."""
        self._core.reset()

    def __getstate__(self) -> dict[str, Any]:
        return self.get_state()

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._core = _core.simulation_from_state(_as_state(state))
        self._scene = None

    def _rows(self, values: object, name: str, width: int = 0) -> np.ndarray:
        """Per-particle values: ``(N,)``, or ``(N, width)``."""
        n = self._core.num_particles
        shape = (n, width) if width else (n,)
        return _args.rows(values, name, shape)

    def __copy__(self) -> Simulation:
        return Simulation.from_state(self.get_state())

    def __deepcopy__(self, memo: dict[int, Any]) -> Simulation:
        return Simulation.from_state(self.get_state())

    # ----- picking, dragging, cutting ------------------------------------------------------

    def pick(self, origin: Vector, direction: Vector) -> tuple[int, float] | None:
        """The live particle the ray ``origin + t direction`` (``t >= 0``) hits first, each
        particle a box of half-size :attr:`pick_radius`: ``(index, distance in m)`` or None.
        Raises :class:`~rustcloth.errors.ParameterError` for a non-finite origin or a zero or
        non-finite direction. Answers bitwise as a brute-force scan would."""
        return self._core.pick(*_ray(origin, direction))

    def pick_triangle(
        self, origin: Vector, direction: Vector
    ) -> tuple[int, float, tuple[float, float, float]] | None:
        """The live triangle (a row of :attr:`triangles`) the ray hits first:
        ``(row, distance in m, barycentric weights of its three vertices)`` or None."""
        return self._core.pick_triangle(*_ray(origin, direction))

    @property
    def pick_radius(self) -> float:
        """Half-size in m of each particle's pick box (default: half the smaller grid
        spacing, or a mesh cloth's mean edge length, so neighbouring boxes touch). Set it to a
        finite number ``> 0``."""
        return self._core.pick_radius

    @pick_radius.setter
    def pick_radius(self, radius: float) -> None:
        self._core.pick_radius = _args.real(radius, "pick_radius")

    @property
    def pick_strategy(self) -> PickStrategyName:
        """``"auto"`` (default: a scan for the first query on a new state, the refitted BVH
        from the second and for long strokes), ``"bvh"`` or ``"scan"``."""
        return cast(PickStrategyName, self._core.pick_strategy)

    @pick_strategy.setter
    def pick_strategy(self, strategy: PickStrategyName) -> None:
        self._core.pick_strategy = _args.text(strategy, "pick_strategy")

    @property
    def grip_radius(self) -> float:
        """Radius in m of the patch of cloth a :meth:`grab` holds (default: 2.5 times the
        smaller grid spacing or a mesh cloth's mean edge length, a patch about five particles
        across). Set it to a finite number
        ``>= 0``; 0 grabs the one particle hit. It applies from the next grab."""
        return self._core.grip_radius

    @grip_radius.setter
    def grip_radius(self, radius: float) -> None:
        self._core.grip_radius = _args.real(radius, "grip_radius")

    @property
    def drag_time(self) -> float:
        """Time in s a :meth:`drag_to` takes to carry the grip to its target, gliding from
        where it is at a constant velocity (default 1/60, a 60 Hz frame: a demo calling
        :meth:`drag_to` once a frame moves the grip continuously at the mouse's speed). A
        shorter time moves it in bursts that jerk the springs round it, and tear them in a fast
        drag; a longer one lags behind the mouse. Set it to a finite number ``>= 0``; 0 puts the
        grip on each target in the next substep. It applies from the next :meth:`drag_to`."""
        return self._core.drag_time

    @drag_time.setter
    def drag_time(self, seconds: float) -> None:
        self._core.drag_time = _args.real(seconds, "drag_time")

    def grab(self, index: int) -> None:
        """Grab the cloth at particle ``index``, as a hand would: that particle and every live
        particle within :attr:`grip_radius` of it, joined to it by live springs inside that
        ball, become kinematic pins where they are, which :meth:`drag_to` moves together.
        Grabbing again releases the first grip."""
        self._core.grab(_args.index(index, "index"))

    def drag_to(self, target: Vector) -> None:
        """Move the grabbed particle's target (m), the rest of the grip keeping its offsets
        from it; they glide there over :attr:`drag_time`. A move into a collider slides the
        whole grip along its surface instead. Does nothing without a grab."""
        self._core.drag_to(_args.floats(target, "target", 3))

    def release(self) -> None:
        """Let go of the grip, restoring the pin state each of its particles had before."""
        self._core.release()

    def grabbed(self) -> int | None:
        """The index of the particle the grip was taken at, or None."""
        return self._core.grabbed()

    def gripped(self) -> list[int]:
        """Every live particle the grip holds, the grabbed one first; empty without a grab."""
        return self._core.gripped()

    def cut_ray(self, origin: Vector, direction: Vector) -> int | None:
        """Cut the particle :meth:`pick` finds; returns its index, or None on a miss."""
        return self._core.cut_ray(*_ray(origin, direction))

    def cut_stroke(self, rays: Sequence[tuple[Vector, Vector]] | npt.ArrayLike) -> list[int]:
        """The seed's cut: remove the particles a mouse stroke passes over. ``rays`` is a
        sequence of ``(origin, direction)`` pairs (or an ``(M, 2, 3)`` array), each cutting the
        particle it picks after the rays before it. Returns the indices cut; their mass leaves
        the cloth. Bad input raises and cuts nothing. :meth:`sever_stroke` cuts like scissors."""
        return self._core.cut_stroke(_args.stroke(rays))

    def sever_stroke(self, rays: Sequence[tuple[Vector, Vector]] | npt.ArrayLike) -> int:
        """Cut the cloth along a mouse stroke, like scissors: every live spring whose segment
        crosses the surface swept between consecutive rays (from each ray's origin through the
        whole cloth) is severed, and the drawn mesh (:meth:`render_mesh`) is clipped along
        where the stroke crossed them. On a mesh cloth the springs are the mesh's edge and
        bend springs (a severed edge takes the bend springs of its triangles with it; only
        the springs the stroke crossed are counted), and its drawn mesh is clipped the same
        way. ``rays`` is a
        sequence of ``(origin, direction)`` pairs (or an ``(M, 2, 3)`` array; directions need
        not be unit). Returns the number of springs severed. No particle is removed: the
        cloth's mass is unchanged to the bit, and a grabbed particle stays grabbed.

        Fewer than two rays, rays that do not move, a stroke that misses the cloth or crosses
        only springs already severed sever nothing and change nothing (``topology_version``
        included). A non-finite origin or a zero or non-finite direction raises ``ValueError``
        naming ``rays[k].origin`` or ``rays[k].direction``, before anything changes."""
        return self._core.sever_stroke(_args.stroke(rays))

    def sever_live_stroke(self, rays: Sequence[tuple[Vector, Vector]] | npt.ArrayLike) -> int:
        """Continue the live cut in progress (a mouse drag over several frames, the cloth
        moving between them) with ``rays``, this frame's samples of it, severing the springs
        it crosses; returns how many. :meth:`end_live_stroke` ends it; the next call starts a
        new one. What the viewer's right drag calls once a frame.

        On a grid cloth the stroke is held in the cloth's own coordinates: each ray that hits
        the cloth names the point of the flat rest sheet under it, and consecutive points (the
        previous frame's last one included) are joined on that sheet, so the cut goes through
        the material the mouse passed over even while the cloth swings, and a stroke from off
        the cloth to off the cloth cuts it in two (where it comes on and goes off, the cut is
        carried out through the cloth's edge on that sheet). Where the stroke jumps to another
        layer (over a fold's edge), that piece is cut by the surface the two rays sweep, as
        :meth:`sever_stroke` does; a mesh cloth is cut that way throughout. Bad rays raise as
        in :meth:`sever_stroke`, changing nothing."""
        return self._core.sever_live_stroke(_args.stroke(rays))

    def end_live_stroke(self) -> None:
        """End the live cut in progress (the mouse button went up)."""
        self._core.end_live_stroke()

    def pieces(self) -> int:
        """The number of pieces the cloth is in: connected components of the live particles
        joined by live springs (O(n)); on a mesh cloth a garment's seams do not join pieces."""
        return self._core.pieces()

    def piece_labels(self) -> npt.NDArray[np.uint32]:
        """The piece each particle belongs to (see :meth:`pieces`), named by the smallest
        particle index in it; ``2**32 - 1`` for a cut particle. ``np.bincount`` of the live
        labels gives each piece's size."""
        return self._core.piece_labels()

    def bvh_stats(self) -> dict[str, int]:
        """Work done on the picking trees: scans, builds, refits and removals."""
        return self._core.bvh_stats()

    # ----- colliders -----------------------------------------------------------------------

    def set_collider_pose(
        self, index: int, position: Vector, rotation: Sequence[float] | npt.ArrayLike
    ) -> None:
        """Put collider ``index`` (of the scene's ``colliders``) at ``position`` (m, its frame's
        origin) turned by ``rotation``, a unit quaternion ``(x, y, z, w)``, by the end of the
        next step.

        Over that step the collider moves there from where it is now at the constant velocity
        and turn rate this takes, and friction acts on the cloth's velocity relative to that
        motion: a cloth resting on a collider posed every step (a box carried by a hand, a
        tracked body) is carried along. After it the collider rests at the pose; its scene
        ``velocity`` and ``angular_velocity`` no longer apply. ``reset()`` returns it to the
        scene's motion; ``get_state()`` and pickling keep the pose.

        Raises ``IndexError`` naming ``index`` for a collider that does not exist, and
        ``ValueError`` naming ``position`` (not finite) or ``rotation`` (not finite, or a norm
        more than 1e-3 from 1; it is normalised), changing nothing.
        """
        index = _args.index(index, "index")
        self._core.set_collider_pose(
            index, _args.floats(position, "position", 3), _args.floats(rotation, "rotation", 4)
        )

    def collider_poses(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Each collider's pose now, in the scene's order: ``(positions, rotations)``, a
        ``(K, 3)`` float64 array in m and a ``(K, 4)`` float64 array of unit quaternions
        ``(x, y, z, w)``. With :meth:`colliders` this is what a renderer draws."""
        return self._core.collider_poses()

    def colliders(self) -> list[dict[str, Any]]:
        """What each collider is, in the scene's order, for drawing it at its
        :meth:`collider_poses` pose: a dict with ``shape`` (``"sphere"``, ``"box"``,
        ``"capsule"``, ``"cylinder"``, ``"plane"`` or ``"mesh"``), ``thickness`` (m) and the
        shape's size keys: ``radius``, ``half_extents``, ``half_height`` (m, capsule and
        cylinder along local y), or ``vertices`` (``(N, 3)`` float64, local frame) and
        ``triangles`` (``(M, 3)`` int64). A plane is the surface local y = 0, solid below."""
        out = []
        for collider in self.scene.colliders:
            shape: dict[str, Any] = {"shape": collider["shape"], "thickness": collider["thickness"]}
            for key in ("radius", "half_extents", "half_height"):
                if key in collider:
                    shape[key] = collider[key]
            if collider["shape"] == "mesh":
                shape["vertices"] = np.asarray(collider["vertices"], dtype=np.float64)
                shape["triangles"] = np.asarray(collider["triangles"], dtype=np.int64)
            out.append(shape)
        return out

    # ----- settings ------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated time in s: each step counted with the ``dt`` it was taken with."""
        return self._core.time

    @property
    def steps(self) -> int:
        """Steps taken since the start or the last reset."""
        return self._core.steps

    @property
    def dt(self) -> float:
        """The fixed time step in s; set it at run time (finite, ``> 0``) to change the
        future: the time already simulated stays as it was."""
        return self._core.dt

    @dt.setter
    def dt(self, dt: float) -> None:
        self._core.dt = _args.real(dt, "dt")
        self._scene = None

    @property
    def substeps(self) -> int:
        """Substeps per step (an integer ``>= 1``); settable at run time."""
        return self._core.substeps

    @substeps.setter
    def substeps(self, substeps: int) -> None:
        self._core.substeps = _args.integer(substeps, "substeps")
        self._scene = None

    @property
    def integrator(self) -> IntegratorName:
        """The time integrator, one of ``rustcloth.INTEGRATORS``; settable at run time (the
        state carries over)."""
        return cast(IntegratorName, self._core.integrator)

    @integrator.setter
    def integrator(self, name: IntegratorName) -> None:
        self._core.integrator = _args.text(name, "integrator")
        self._scene = None

    @property
    def self_collision(self) -> SelfCollisionSettings | None:
        """The self-collision pass's settings (``thickness``, ``friction``, ``iterations``), or
        None while it is off. Settable at run time, the state carrying over bit for bit: a
        dict of ``[self_collision]`` settings (missing keys take their defaults) or True (all
        defaults) turns it on, None or False turns it off. Settings the scene would refuse
        raise :class:`~rustcloth.errors.ParameterError` naming the key (a ``thickness`` past
        half the grid spacing), anything else :class:`TypeError`, changing nothing. The
        :meth:`profile` and :meth:`self_collision_stats` start afresh."""
        return self.scene.self_collision

    @self_collision.setter
    def self_collision(self, settings: SelfCollisionSettings | bool | None) -> None:
        if settings is True:
            table: dict[str, Any] | None = {}
        elif settings is None or settings is False:
            table = None
        elif isinstance(settings, Mapping):
            table = dict(settings)
        else:
            _args.type_error("self_collision", "must be a dict of [self_collision] settings, "
                             f"True, False or None, got {_args.got(settings)}")
        self._core.set_self_collision(table)
        self._scene = None

    @property
    def scene(self) -> Scene:
        """The scene, with the run-time settings (integrator, substeps, dt) as they are now.
        Built once and kept until a setting changes."""
        if self._scene is None:
            self._scene = Scene.from_dict(self._core.scene_dict())
        return self._scene

    @property
    def nx(self) -> int:
        """Particles along ``i``."""
        return self._core.nx

    @property
    def ny(self) -> int:
        """Particles along ``j``."""
        return self._core.ny

    @property
    def num_particles(self) -> int:
        """``nx * ny``: rows of every per-particle array."""
        return self._core.num_particles

    # ----- diagnostics ---------------------------------------------------------------------

    def energy(self) -> Energy:
        """Kinetic, gravitational potential and elastic energy in J, summed in float64 over
        fixed chunks: bitwise the same for any thread count."""
        return Energy(*self._core.energy())

    def spring_strain(self) -> FloatArray:
        """``(N,)`` float32: per particle, the largest ``l / L - 1`` of its live springs."""
        return self._core.spring_strain()

    def max_stretch(self) -> float:
        """The largest ``l / L - 1`` over all live springs of the active families."""
        return self._core.max_stretch()

    @property
    def effects(self) -> list[str]:
        """The passes a step runs, in order: only those the scene asked for."""
        return self._core.effects

    def profile(self) -> Profile:
        """Wall time spent in each pass since the start or the last reset."""
        passes, steps, total = self._core.profile()
        return Profile(
            passes={name: PassTime(name, seconds, calls) for name, seconds, calls in passes},
            steps=steps,
            total_seconds=total,
            solver=self.solver_stats(),
            integrator=self.integrator,
        )

    def solver_stats(self) -> dict[str, float] | None:
        """The implicit solver's statistics (see :attr:`Profile.solver`), or None."""
        return self._core.solver_stats()

    def stable_dt(self) -> float | None:
        """The largest ``dt`` (s) the current integrator is estimated to be stable at with the
        current substeps and the lightest moving particle, or None when any is."""
        return self._core.stable_dt()

    def self_collision_stats(self) -> dict[str, float] | None:
        """What the self-collision pass did since the simulation was built, or None without
        ``[self_collision]``: ``substeps`` it ran, candidate ``pairs`` and ``contacts`` (pairs
        closer than ``thickness``) summed over substeps, substeps on the pair list that looked
        at every pair they needed, not only those their motion can bring near (``widened``),
        ``rebuilds`` of its pair list and
        ``requeries`` of part of it (``requeried`` vertices, summed), vertices the cap slowed
        (``capped``) or ``stopped``, the most cap rounds in one substep (``max_cap_rounds``),
        the smallest distance between a vertex and a triangle, or two edges, at the start
        of a substep (``min_distance``, m), and, with ``solve_stiffness``, the swept searches
        run ahead of implicit Euler's solves (``ahead_searches``; skipped where a list of its
        own holds every pair they could find), the steps whose pairs ahead that list gave
        instead (``ahead_from_list``; not counted: those it showed have none), that list's
        builds (``ahead_rebuilds``), the steps whose pairs ahead it showed all too far apart
        to be held and left out (``ahead_apart``) and of those the steps whose solve moved
        far enough to ask for them and was solved again (``ahead_asked``), the solves given the
        last pairs ahead again, from the same start along the same paths to the bit, as a
        substep's passes run again (``ahead_again``; not searched or listed), the substeps whose
        pass took its pairs from the step's one search instead of searching again
        (``pass_from_ahead``) and the vertices it looked up on their own there, the solve having
        ended them outside their budget (``pass_outside``, summed), and substeps drawn
        back along their paths because the cap
        left the cloth with energy nothing gave it (``drawn_back``)."""
        return self._core.self_collision_stats()

    def seam_gap(self) -> float | None:
        """How far a garment's seams are from closed: the largest distance (m) between two
        vertices sewn together, or None when the cloth has no seams. The seams close over
        their ``sew_time``, then hold the gap to about a millimetre (docs/garments.md)."""
        return self._core.seam_gap()

    def watchdog_stats(self) -> dict[str, int]:
        """What the watchdog caught (``caught``), saved by retrying (``retried``), the
        substeps those retries cost (``retry_substeps``), the most a saved step needed
        (``max_substeps_used``), the steps run with held substeps (``held_steps``) and the
        most vertices the self-collision cap stopped in one substep of a step saved from a
        cascade (``largest_cascade``, what chooses its hold; 0 without one)."""
        return self._core.watchdog_stats()

    def memory_bytes(self) -> int:
        """Heap memory held by the simulation in bytes, picking trees included."""
        return self._core.memory_bytes()

    def __repr__(self) -> str:
        return (
            f"<Simulation {self.nx}x{self.ny} {self.integrator} dt={self.dt:g} "
            f"t={self.time:.4f}s effects={self.effects}>"
        )

    def to_mesh(self) -> Mesh:
        """The current frame's drawn mesh (:meth:`render_mesh`) as a
        :class:`rustcloth.mesh.Mesh`: ``vertices`` ``(V, 3)`` float32 in m (vertex ``p < N``
        is particle ``p``; cut particles stay, used by no triangle; the cut vertices follow),
        ``triangles`` ``(T, 3)`` uint32, ``normals`` ``(V, 3)`` float32 unit vectors and
        ``uvs`` ``(V, 2)`` float32, particle ``(i, j)`` at ``(i / (nx - 1), j / (ny - 1))``."""
        return Mesh.from_arrays(*self.render_mesh()[:4])

    def export(self, path: str | os.PathLike[str]) -> Path:
        """Write the current frame to ``path`` (a ``str`` or ``os.PathLike``) as ``.obj``,
        ``.ply`` or ``.glb`` (glTF binary), with normals and UVs, through trimesh
        (``pip install 'rustcloth[export]'``; ``ImportError`` naming the extra otherwise).
        ``ValueError`` for another suffix. Returns the ``pathlib.Path`` written. A whole run:
        :func:`rustcloth.export.recorder`."""
        # Called, not imported at the top: rustcloth.export takes a Simulation, and the
        # dependency runs one way, from the writers to the simulation.
        from .export import export

        return export(self, path)
