"""Replayable scripts of gestures and key presses (``--script``, ``--demo-script``, the tests):
events at times on the viewer's clock, played through the same handlers a person uses."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..camera import Camera
from .keys import command_for

ACTIONS = ("grab", "drag", "release", "cut", "orbit", "key")


class ScriptInput(Protocol):
    """Where scripted input goes: the viewer's pointer and keys, or the glfw window's
    handlers (so a scripted press is a real button press there)."""

    @property
    def size(self) -> tuple[int, int]: ...
    @property
    def camera(self) -> Camera: ...
    @property
    def pos(self) -> tuple[float, float]: ...
    def press(self, mode: str, x: float, y: float) -> None: ...
    def move(self, x: float, y: float) -> None: ...
    def release(self) -> None: ...
    def key(self, name: str) -> None: ...


@dataclass
class ScriptPlayer:
    """Replays events ``{"t": seconds, "action": ...}``:

    - ``grab``: press at a point; ``drag``: move there over ``duration`` seconds (default 0);
      ``release``; ``cut``: press at the first point of ``path``, sweep the rest over
      ``duration``, release; ``orbit``: ``{"yaw": rad, "pitch": rad}``; ``key``:
      ``{"key": "I"}``, a key press (names as in the help: SPACE, N, R, I, V, L, 1, ...).

    A point is ``"x"``/``"y"`` as fractions of the window, ``"particle"`` (an index, at its
    current place on screen) or ``"world"`` ([x, y, z]). Events fire on the viewer's clock,
    so the same script and frame rate give the same frames.
    """

    events: list[dict[str, Any]]
    _queue: list[dict[str, Any]] = field(init=False)
    _moves: list[tuple[float, float, list[tuple[float, float]], bool]] = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.events, list):
            raise ValueError(f"a script is a JSON list of events, got {type(self.events).__name__}")
        for k, e in enumerate(self.events):
            if not isinstance(e, dict) or "t" not in e or "action" not in e:
                raise ValueError(f"script event {k} needs 't' and 'action': {e!r}")
            if e["action"] not in ACTIONS:
                raise ValueError(f"script event {k}: unknown action {e['action']!r}; "
                                 f"actions: {', '.join(ACTIONS)}")
            if e["action"] == "key" and command_for(str(e.get("key", ""))) is None:
                raise ValueError(f"script event {k}: unknown key {e.get('key')!r}")
        self._queue = sorted(self.events, key=lambda e: float(e["t"]))
        self._moves = []

    @classmethod
    def load(cls, path: str | Path) -> ScriptPlayer:
        return cls(json.loads(Path(path).read_text(encoding="utf-8")))

    @property
    def done(self) -> bool:
        return not self._queue and not self._moves

    @property
    def end(self) -> float:
        """When the last event is over, in seconds."""
        return max((float(e["t"]) + float(e.get("duration", 0.0)) for e in self.events),
                   default=0.0)

    def _point(self, spec: Any, sink: ScriptInput, positions: npt.NDArray[np.float32]
               ) -> tuple[float, float]:
        w, h = sink.size
        if isinstance(spec, list | tuple):
            return float(spec[0]) * w, float(spec[1]) * h
        if "particle" in spec:
            px, py, _ = sink.camera.project(positions[int(spec["particle"])], w, h)
            return px, py
        if "world" in spec:
            px, py, _ = sink.camera.project(spec["world"], w, h)
            return px, py
        return float(spec["x"]) * w, float(spec["y"]) * h

    def update(self, t: float, sink: ScriptInput, positions: npt.NDArray[np.float32]) -> None:
        """Apply everything due by time ``t`` (seconds since the script started)."""
        while self._queue and float(self._queue[0]["t"]) <= t + 1e-9:
            e = self._queue.pop(0)
            start, action = float(e["t"]), e["action"]
            duration = float(e.get("duration", 0.0))
            if action == "grab":
                sink.press("grab", *self._point(e, sink, positions))
            elif action == "drag":
                target = self._point(e, sink, positions)
                self._moves.append((start, duration, [sink.pos, target], False))
            elif action == "release":
                sink.release()
            elif action == "orbit":
                sink.camera.orbit(float(e.get("yaw", 0.0)), float(e.get("pitch", 0.0)))
            elif action == "key":
                sink.key(str(e["key"]))
            elif action == "cut":
                path = [self._point(p, sink, positions) for p in e["path"]]
                sink.press("cut", *path[0])
                self._moves.append((start, duration, path, True))
        still = []
        for start, duration, path, release in self._moves:
            # Progress along the path (a polyline) as a fraction of its duration.
            f = 1.0 if duration <= 0 else min(1.0, (t - start) / duration)
            pts = path if len(path) > 1 else [*path, *path]
            seg = f * (len(pts) - 1)
            k = min(int(seg), len(pts) - 2)
            a, b = pts[k], pts[k + 1]
            u = seg - k
            sink.move(a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u)
            if f < 1.0:
                still.append((start, duration, path, release))
            elif release:
                sink.release()
        self._moves = still


def default_script(nx: int, ny: int, positions: npt.NDArray[np.float32], span: float,
                   duration: float) -> list[dict[str, Any]]:
    """A cut, then a grab and drag, spread over a run of ``duration`` seconds so that every
    part of it shows: cut across the cloth once it has settled a little, then lift the
    particle at its middle and let go."""
    d = max(duration, 0.5)
    middle = (ny // 2) * nx + nx // 2
    p = positions[middle]
    target = [float(p[0]), float(p[1]) + 0.25 * span, float(p[2])]
    row = (2 * ny) // 3
    return [
        {"t": 0.20 * d, "action": "cut", "duration": 0.15 * d,
         "path": [{"particle": row * nx + 1}, {"particle": row * nx + nx - 2}]},
        {"t": 0.45 * d, "action": "grab", "particle": middle},
        {"t": 0.47 * d, "action": "drag", "world": target, "duration": 0.2 * d},
        {"t": 0.80 * d, "action": "release"},
    ]
