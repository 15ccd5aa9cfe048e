"""What a sweep runs and records: :class:`Sweep`, :class:`Record`, :class:`Filters`, and their
expansion into :class:`Run` objects, each validated before any of them starts.

A sweep is a base scene plus overrides (a grid, a list of runs, or both), or a function of each
run's parameters that returns a :class:`~rustcloth.Scene`. Every run is expanded, built into a
scene and validated in the driver, so a bad description fails before the first simulation.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import importlib
import importlib.util
import itertools
import json
import math
import os
import pickle
import stat
import sys
import tomllib
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import _core
from .._limits import MAX_STEPS
from ..scene import Scene, load_scene

#: Version of the run format; part of every run id, so a change of format reruns everything.
FORMAT = 1

#: The largest sweep file read (a description of a million runs is far smaller).
MAX_FILE_BYTES = 16 * 2**20

#: npz keys the recorder writes itself; a user function may not take one of these names.
RESERVED = frozenset(
    {"steps", "time", "positions", "energy", "max_stretch", "final_positions", "triangles",
     "meta"}
)


class SweepError(ValueError):
    """A sweep description that cannot run: an unknown key, an empty grid, a bad value, a scene
    function that returns something other than a Scene. The message names the key."""


# ---------------------------------------------------------------------------------------------
# Functions named by "module:attr" or "path/to/file.py:attr"


class FunctionRef:
    """A function named by ``"package.module:name"`` or ``"path/file.py:name"``, imported where
    it is first called or resolved (never when the reference is made). It pickles as its name,
    so a worker (another process, another machine) imports it itself; a file path is made
    absolute when the reference is made."""

    __slots__ = ("spec", "_fn")

    def __init__(self, spec: str, base_dir: str | os.PathLike[str] | None = None) -> None:
        module, sep, attr = spec.rpartition(":")
        if not sep or not module or not attr:
            raise SweepError(f"function {spec!r}: expected 'module:name' or 'file.py:name'")
        if module.endswith(".py"):
            module = os.path.abspath(os.path.join(base_dir or os.getcwd(), module))
        self.spec = f"{module}:{attr}"
        self._fn: Callable[..., Any] | None = None

    def resolve(self) -> Callable[..., Any]:
        if self._fn is None:
            module_name, _, attr = self.spec.rpartition(":")
            try:
                if module_name.endswith(".py"):
                    name = "_rustcloth_sweep_" + hashlib.sha1(module_name.encode()).hexdigest()[:12]
                    module = sys.modules.get(name)
                    if module is None:
                        spec = importlib.util.spec_from_file_location(name, module_name)
                        if spec is None or spec.loader is None:
                            raise ImportError(f"cannot load {module_name}")
                        module = importlib.util.module_from_spec(spec)
                        sys.modules[name] = module
                        spec.loader.exec_module(module)
                else:
                    module = importlib.import_module(module_name)
                fn = module
                for part in attr.split("."):
                    fn = getattr(fn, part)
            except (ImportError, AttributeError, OSError) as err:
                raise SweepError(f"function {self.spec!r} cannot be loaded: {err}") from None
            if not callable(fn):
                raise SweepError(f"function {self.spec!r} is a {type(fn).__name__}, not callable")
            self._fn = fn
        return self._fn

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.resolve()(*args, **kwargs)

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        return (FunctionRef, (self.spec,))

    def __repr__(self) -> str:
        return f"FunctionRef({self.spec!r})"


def _function(value: Any, what: str, base_dir: str | None) -> Callable[..., Any]:
    """A callable, or a FunctionRef for a string (not imported yet: see :func:`_resolved`)."""
    if isinstance(value, str):
        return FunctionRef(value, base_dir)
    if not callable(value):
        raise SweepError(f"{what} must be a function or 'module:name', got {type(value).__name__}")
    return value  # type: ignore[no-any-return]


def _resolved(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn``, imported now if it is a reference, so that a typo fails before any run."""
    if isinstance(fn, FunctionRef):
        fn.resolve()
    return fn


def _check_file_functions(data: Mapping[str, Any], base_dir: str,
                          modules: Collection[str]) -> None:
    """A sweep file is code: the functions it names run in this process. Allow only ``.py``
    files in the file's own folder (or below it) and modules the caller named in ``modules``,
    so that a file from elsewhere cannot reach ``os:system`` or a file of its choosing."""
    record, filters = data.get("record"), data.get("filters")
    named = [("scene_fn", data.get("scene_fn"))]
    if isinstance(record, Mapping) and isinstance(record.get("functions"), Mapping):
        named += [(f"record.functions.{k}", v) for k, v in record["functions"].items()]
    if isinstance(filters, Mapping):
        named.append(("filters.reject", filters.get("reject")))
    home = os.path.realpath(base_dir)
    for what, spec in named:
        if not isinstance(spec, str):
            continue
        module = spec.rpartition(":")[0]
        if module.endswith(".py"):
            path = os.path.realpath(os.path.join(home, module))
            if os.path.commonpath([path, home]) != home:
                raise SweepError(f"{what} = {spec!r}: a sweep file may load .py files only from "
                                 f"its own folder, {home}")
        elif module not in modules:
            raise SweepError(f"{what} = {spec!r}: a sweep file imports a module only when the "
                             f"command names it (rustcloth sweep --module {module})")


def _fingerprint(fn: Callable[..., Any]) -> str:
    """A function's name as it enters a run id: its code is not hashed (see docs/sweeps.md)."""
    if isinstance(fn, FunctionRef):
        return fn.spec
    return f"{getattr(fn, '__module__', '?')}:{getattr(fn, '__qualname__', repr(fn))}"


# ---------------------------------------------------------------------------------------------
# What to record, what to keep


@dataclass(frozen=True)
class Record:
    """What each run records. Frames are taken at steps ``0, every, 2 every, ...`` and at the
    last step; with ``every = 0`` only at the last step.

    ``positions``: ``(F, N, 3)`` float32 at each frame. ``energy``: ``(F, 3)`` float64,
    kinetic, gravitational and elastic J. ``max_stretch``: ``(F,)`` largest ``l / L - 1``.
    ``final_mesh``: ``final_positions`` ``(N, 3)`` float32 and ``triangles`` ``(T, 3)``
    uint32 after the last step. ``functions``: ``{name: f}``, each ``f(simulation)`` returning
    an array (or number) at each frame, stacked into ``(F, ...)`` under ``name``. A function is
    a picklable callable (importable by name: a module-level function) or ``"module:name"``.
    """

    every: int = 0
    positions: bool = True
    energy: bool = True
    max_stretch: bool = True
    final_mesh: bool = True
    functions: Mapping[str, Callable[..., Any]] = field(default_factory=dict)

    def fingerprint(self) -> dict[str, Any]:
        return {
            "every": self.every,
            "positions": self.positions,
            "energy": self.energy,
            "max_stretch": self.max_stretch,
            "final_mesh": self.final_mesh,
            "functions": {name: _fingerprint(fn) for name, fn in self.functions.items()},
        }


@dataclass(frozen=True)
class Filters:
    """Quality filters, applied to a run's results in the worker: a run that fails one is
    recorded with status ``"filtered"`` and its reason, and its arrays are not written.

    ``max_stretch``: drop a run whose largest recorded stretch (``l / L - 1`` at any frame,
    or after the last step) exceeds this. ``reject``: ``f(arrays) -> str | None``, given the
    run's arrays; a string drops the run with that reason.
    """

    max_stretch: float | None = None
    reject: Callable[..., Any] | None = None

    def fingerprint(self) -> dict[str, Any]:
        return {
            "max_stretch": self.max_stretch,
            "reject": None if self.reject is None else _fingerprint(self.reject),
        }


# ---------------------------------------------------------------------------------------------
# One run


@dataclass(frozen=True)
class Run:
    """One simulation of a sweep, as sent to a worker: everything its result depends on.

    ``run_id`` is a hash of ``params``, the scene, ``steps``, the record and the filters, so
    the same run has the same id (and the same file) in every sweep that contains it."""

    index: int
    run_id: str
    params: dict[str, Any]
    scene: dict[str, Any]
    steps: int
    record: Record
    filters: Filters
    time_limit: float | None = None


def _plain(value: Any, what: str, depth: int = 0) -> Any:
    """A parameter value as JSON data (numpy scalars and arrays become numbers and lists).
    Nested no deeper than a scene may be (``_core.MAX_NESTING``): deeper input would exhaust
    the recursion here, and no scene could take it."""
    if depth > _core.MAX_NESTING:
        raise SweepError(f"{what}: lists and tables nest at most {_core.MAX_NESTING} deep")
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Mapping):
        return {str(k): _plain(v, what, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v, what, depth + 1) for v in value]
    if value is None or isinstance(value, bool | int | float | str):
        if isinstance(value, float) and not math.isfinite(value):
            raise SweepError(f"{what}: {value!r} is not a finite number")
        return value
    raise SweepError(f"{what}: {type(value).__name__} values cannot be recorded; use numbers, "
                     "strings, booleans or lists of them")


def _flatten(overrides: Mapping[str, Any], what: str, prefix: str = "") -> dict[str, Any]:
    """``{"cloth": {"k_bend": 1}}`` and ``{"cloth.k_bend": 1}`` both become the latter."""
    if not isinstance(overrides, Mapping):
        raise SweepError(f"{what} must be a table of keys, got {type(overrides).__name__}")
    flat: dict[str, Any] = {}
    for key, value in overrides.items():
        if not isinstance(key, str) or not key:
            raise SweepError(f"{what}: keys must be non-empty strings, got {key!r}")
        path = prefix + key
        if isinstance(value, Mapping) and value:
            flat.update(_flatten(value, what, path + "."))
        else:
            flat[path] = value
    return flat


def apply_overrides(scene: dict[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """The scene dict with dotted keys set: ``cloth.k_bend``, ``floor.height``,
    ``spheres.0.radius`` (an index into a list). Tables missing from the base (``floor`` when
    the base has none) are created; the scene's own validation judges the result."""
    data = copy.deepcopy(scene)
    for key, value in overrides.items():
        node: Any = data
        parts = key.split(".")
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            where = ".".join(parts[: depth + 1])
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SweepError(f"unknown scene key {key!r}: {where!r} is not an index "
                                     f"into a list of {len(node)}")
                index = int(part)
                if last:
                    node[index] = value
                else:
                    node = node[index]
            elif isinstance(node, dict):
                if last:
                    node[part] = value
                else:
                    if node.get(part) is None:
                        node[part] = {}
                    node = node[part]
            else:
                raise SweepError(f"unknown scene key {key!r}: {'.'.join(parts[:depth])!r} is "
                                 f"a {type(node).__name__}, not a table")
    return data


# ---------------------------------------------------------------------------------------------
# The sweep


_SWEEP_KEYS = ("base", "scene_fn", "grid", "runs", "seconds", "steps", "time_limit", "record",
               "filters")


@dataclass(frozen=True)
class Sweep:
    """A description of many runs.

    ``base``: a :class:`~rustcloth.Scene`, a scene dict, a built-in scene name or a scene TOML
    path. ``scene_fn``: instead of ``base``, a function ``scene_fn(**params) -> Scene`` (or
    ``"module:name"``), called in the driver once per run before any run starts. ``grid``:
    ``{key: [values]}``, every combination; ``runs``: a list of ``{key: value}``; given both,
    each run is combined with each grid point. With ``base`` the keys are scene keys, dotted
    for tables (``cloth.k_bend``, ``spheres.0.radius``); with ``scene_fn`` they are the
    function's keyword arguments. Each run lasts ``steps`` steps or ``seconds`` of simulated
    time (``round(seconds / dt)`` steps of that run's ``dt``). ``time_limit``: wall seconds per
    run, after which it is stopped and recorded as ``"timeout"``.
    """

    base: Scene | Mapping[str, Any] | str | None = None
    scene_fn: Callable[..., Any] | str | None = None
    grid: Mapping[str, Sequence[Any]] | None = None
    runs: Sequence[Mapping[str, Any]] | None = None
    seconds: float | None = None
    steps: int | None = None
    time_limit: float | None = None
    record: Record = field(default_factory=Record)
    filters: Filters = field(default_factory=Filters)
    #: Where relative file names in the description are resolved (the TOML file's folder).
    base_dir: str | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | None = None) -> Sweep:
        """A sweep from a dict with the keys of ``sweep.toml`` (docs/sweeps.md)."""
        if not isinstance(data, Mapping):
            raise SweepError(f"a sweep description must be a table, got {type(data).__name__}")
        unknown = sorted(set(data) - set(_SWEEP_KEYS))
        if unknown:
            raise SweepError(f"unknown sweep key {unknown[0]!r}; expected one of "
                             f"{', '.join(_SWEEP_KEYS)}")
        values = dict(data)
        record = values.pop("record", {})
        filters = values.pop("filters", {})
        if isinstance(record, Mapping):
            record = _record_from_dict(record, base_dir)
        if isinstance(filters, Mapping):
            filters = _filters_from_dict(filters, base_dir)
        return cls(**values, record=record, filters=filters, base_dir=base_dir)

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str], modules: Collection[str] = ()) -> Sweep:
        """A sweep from ``sweep.toml``; file names in it are relative to its folder.

        A sweep file is code: its functions (``scene_fn``, ``record.functions``,
        ``filters.reject``) run in this process. They may name ``.py`` files in the file's own
        folder, and modules only if listed in ``modules``; nothing is imported here (only when
        the sweep is expanded)."""
        try:
            with open(path, "rb") as f:
                # A device (/dev/zero, /dev/full) reads forever: take regular files only, and
                # no more of one than a description can sensibly be.
                if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                    raise SweepError(f"{os.fspath(path)!r} is not a regular file")
                text = f.read(MAX_FILE_BYTES + 1)
            if len(text) > MAX_FILE_BYTES:
                raise SweepError(f"{os.fspath(path)!r} is over {MAX_FILE_BYTES:,} bytes; is it "
                                 "a sweep description?")
            data = tomllib.loads(text.decode("utf-8"))
        except OSError as err:
            raise SweepError(f"cannot read {os.fspath(path)!r}: {err.strerror}") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
            raise SweepError(f"{os.fspath(path)}: {err}") from None
        except RecursionError:
            raise SweepError(f"{os.fspath(path)}: nested too deeply to read") from None
        base_dir = os.path.dirname(os.path.abspath(path))
        _check_file_functions(data, base_dir, modules)
        return cls.from_dict(data, base_dir=base_dir)

    # -- expansion ---------------------------------------------------------------------------

    def points(self) -> list[dict[str, Any]]:
        """The parameters of every run, in order: each of ``runs`` with each grid point."""
        runs: list[dict[str, Any]]
        if self.runs is None:
            runs = [{}]
        else:
            if isinstance(self.runs, Mapping | str) or not isinstance(self.runs, Sequence):
                raise SweepError("runs must be a list of tables")
            if not self.runs:
                raise SweepError("runs is empty: give at least one run, or leave it out")
            runs = [self._keys(run, f"runs[{i}]") for i, run in enumerate(self.runs)]
        grid: dict[str, list[Any]] = {}
        if self.grid is not None:
            flat = self._keys(self.grid, "grid")
            if not flat:
                raise SweepError("grid is empty: give at least one key with a list of values")
            for key, values in flat.items():
                if isinstance(values, str | bytes) or not isinstance(values, Sequence | np.ndarray):
                    raise SweepError(f"grid key {key!r} needs a list of values, got "
                                     f"{type(values).__name__} {values!r}")
                if len(values) == 0:
                    raise SweepError(f"grid key {key!r} has no values")
                grid[key] = [_plain(v, f"grid key {key!r}") for v in values]
        points = []
        for run in runs:
            clash = sorted(set(run) & set(grid))
            if clash:
                raise SweepError(f"key {clash[0]!r} is set both by runs and by the grid")
            for combo in itertools.product(*grid.values()):
                points.append({**run, **dict(zip(grid, combo, strict=True))})
        return points

    def _keys(self, table: Any, what: str) -> dict[str, Any]:
        if self.scene_fn is not None:  # keyword arguments: plain names, taken as they are
            if not isinstance(table, Mapping):
                raise SweepError(f"{what} must be a table of keys, got {type(table).__name__}")
            for key in table:
                if not isinstance(key, str) or not key.isidentifier():
                    raise SweepError(f"{what}: {key!r} is not a keyword argument name")
            return {k: _plain(v, f"{what} key {k!r}") for k, v in table.items()}
        flat = _flatten(table, what)
        return {k: _plain(v, f"{what} key {k!r}") for k, v in flat.items()}

    def expand(self) -> list[Run]:
        """Every run, each scene built and validated: raises :class:`SweepError` (or the scene's
        own ``ParameterError``/``ParameterTypeError``, naming the key) before any run starts.
        It holds every run's scene at once: :meth:`iter_runs` makes them one at a time."""
        return list(self.iter_runs())

    def iter_runs(self) -> Iterator[Run]:
        """The runs of :meth:`expand`, built one at a time as they are taken (a large sweep
        never holds every scene). The description is checked, and its functions imported, when
        the first run is taken; a run's own scene when it is reached."""
        record, filters = self._check()
        scene_fn = None if self.scene_fn is None else _resolved(
            _function(self.scene_fn, "scene_fn", self.base_dir))
        record = dataclasses.replace(record, functions={
            k: _resolved(f) for k, f in record.functions.items()})
        if filters.reject is not None:
            filters = dataclasses.replace(filters, reject=_resolved(filters.reject))
        base = None if self.base is None else self._base_scene().to_dict()
        seen: dict[str, int] = {}
        for index, params in enumerate(self.points()):
            if scene_fn is not None:
                scene = scene_fn(**params)
                if not isinstance(scene, Scene):
                    raise SweepError(
                        f"scene_fn({_show(params)}) returned {type(scene).__name__}, not a "
                        "rustcloth.Scene (build one with Scene(...) or Scene.from_dict)")
                data = scene.to_dict()
            else:
                assert base is not None
                data = _overridden(base, index, params)
            steps = self._steps(index, data["dt"])
            run_id = _run_id(params, data, steps, record, filters)
            if run_id in seen:
                raise SweepError(f"runs {seen[run_id]} and {index} are the same run "
                                 f"({_show(params)})")
            seen[run_id] = index
            yield Run(index, run_id, params, data, steps, record, filters, self.time_limit)

    def preview(self) -> Iterator[Planned]:
        """What ``--dry-run`` lists, importing nothing the description names: each run's index
        and parameters, and, with ``base``, its run id and steps (with ``scene_fn`` those need
        the function's scene, so they are None)."""
        record, filters = self._check()
        if self.scene_fn is not None:
            for index, params in enumerate(self.points()):
                yield Planned(index, None, params, self.steps)
            return
        base = self._base_scene().to_dict()
        for index, params in enumerate(self.points()):
            data = _overridden(base, index, params)
            steps = self._steps(index, data["dt"])
            yield Planned(index, _run_id(params, data, steps, record, filters), params, steps)

    def _check(self) -> tuple[Record, Filters]:
        """The checks of the description that need no scene and import nothing."""
        record = _check_record(self.record)
        filters = _check_filters(self.filters)
        if (self.base is None) == (self.scene_fn is None):
            raise SweepError("give exactly one of base (a scene) and scene_fn (a function)")
        if (self.seconds is None) == (self.steps is None):
            raise SweepError("give exactly one of seconds and steps (how long each run lasts)")
        if self.seconds is not None and not _positive(self.seconds):
            raise SweepError(f"seconds must be a positive number, got {self.seconds!r}")
        if self.steps is not None and not (_is_int(self.steps) and 1 <= self.steps <= MAX_STEPS):
            raise SweepError(f"steps must be a whole number from 1 to {MAX_STEPS:,}, got "
                             f"{self.steps!r}")
        if self.time_limit is not None and not _positive(self.time_limit):
            raise SweepError(f"time_limit must be a positive number of seconds, got "
                             f"{self.time_limit!r}")
        if filters.max_stretch is not None and not record.max_stretch:
            raise SweepError("filters.max_stretch needs record.max_stretch = true")
        return record, filters

    def _steps(self, index: int, dt: float) -> int:
        """Run ``index``'s step count: ``steps``, or ``seconds`` in whole steps of its dt."""
        if self.steps is not None:
            return int(self.steps)
        assert self.seconds is not None
        wanted = self.seconds / dt
        if not wanted <= MAX_STEPS:
            raise SweepError(f"seconds = {self.seconds!r} is more than {MAX_STEPS:,} steps of "
                             f"run {index}'s dt = {dt:g} s")
        return max(1, round(wanted))

    def _base_scene(self) -> Scene:
        base = self.base
        if isinstance(base, Scene):
            return base
        if isinstance(base, Mapping):
            return Scene.from_dict(base)
        if isinstance(base, str | os.PathLike):
            path = os.path.join(self.base_dir, base) if self.base_dir else base
            if str(base).endswith(".toml") or os.path.isfile(path):
                return load_scene(os.fspath(path))
            return load_scene(base)
        raise SweepError(f"base must be a Scene, a table, a built-in scene name or a TOML path, "
                         f"got {type(base).__name__}")

    def to_dict(self) -> dict[str, Any]:
        """The description as data (functions by name), as written to ``sweep.json``."""
        base: Any = self.base
        if isinstance(base, Scene):
            base = base.to_dict()
        elif isinstance(base, os.PathLike):
            base = os.fspath(base)
        fn = self.scene_fn
        return {
            "base": base,
            "scene_fn": None if fn is None else (fn if isinstance(fn, str) else _fingerprint(fn)),
            "grid": None if self.grid is None else {k: _plain(v, k) for k, v in
                                                    _flatten(self.grid, "grid").items()},
            "runs": None if self.runs is None else [_plain(dict(r), "runs") for r in self.runs],
            "seconds": self.seconds,
            "steps": self.steps,
            "time_limit": self.time_limit,
            "record": self.record.fingerprint(),
            "filters": self.filters.fingerprint(),
        }


@dataclass(frozen=True, slots=True)
class Planned:
    """A run as :meth:`Sweep.preview` lists it (``run_id`` and ``steps`` None where only the
    scene function could tell)."""

    index: int
    run_id: str | None
    params: dict[str, Any]
    steps: int | None


def _overridden(base: dict[str, Any], index: int, params: Mapping[str, Any]) -> dict[str, Any]:
    """Run ``index``'s scene: the base with its overrides, validated (an error names the run)."""
    try:
        return Scene.from_dict(apply_overrides(base, params)).to_dict()
    except (ValueError, TypeError) as err:
        raise type(err)(f"run {index} ({_show(params)}): {err}") from None


def _show(params: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in params.items()) or "the base scene"


def _positive(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def _is_int(x: Any) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool)


def _run_id(params: Mapping[str, Any], scene: Mapping[str, Any], steps: int, record: Record,
            filters: Filters) -> str:
    key = {"format": FORMAT, "params": params, "scene": scene, "steps": steps,
           "record": record.fingerprint(), "filters": filters.fingerprint()}
    text = json.dumps(key, sort_keys=True, separators=(",", ":"), default=_json_array)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _json_array(value: Any) -> Any:
    """A numpy array (a scene's mesh vertices and triangles) as the lists JSON writes, so that
    a run's id is the same whichever way the mesh was given."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def _record_from_dict(data: Mapping[str, Any], base_dir: str | None) -> Record:
    known = {"every", "positions", "energy", "max_stretch", "final_mesh", "functions"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise SweepError(f"unknown record key {unknown[0]!r}; expected one of "
                         f"{', '.join(sorted(known))}")
    values = dict(data)
    functions = values.pop("functions", {})
    if not isinstance(functions, Mapping):
        raise SweepError("record.functions must be a table of name = 'module:function'")
    functions = {name: _function(fn, f"record.functions.{name}", base_dir)
                 for name, fn in functions.items()}
    return Record(**values, functions=functions)


def _filters_from_dict(data: Mapping[str, Any], base_dir: str | None) -> Filters:
    known = {"max_stretch", "reject"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise SweepError(f"unknown filters key {unknown[0]!r}; expected one of "
                         f"{', '.join(sorted(known))}")
    reject = data.get("reject")
    return Filters(max_stretch=data.get("max_stretch"),
                   reject=None if reject is None else _function(reject, "filters.reject",
                                                                base_dir))


def _check_record(record: Any) -> Record:
    if not isinstance(record, Record):
        raise SweepError(f"record must be a Record or a table, got {type(record).__name__}")
    if not (_is_int(record.every) and record.every >= 0):
        raise SweepError(f"record.every must be a whole number of steps >= 0, got "
                         f"{record.every!r}")
    for name in ("positions", "energy", "max_stretch", "final_mesh"):
        if not isinstance(getattr(record, name), bool):
            raise SweepError(f"record.{name} must be true or false, got "
                             f"{getattr(record, name)!r}")
    if not isinstance(record.functions, Mapping):
        raise SweepError("record.functions must map names to functions")
    functions = {}
    for name, fn in record.functions.items():
        if not isinstance(name, str) or not name.isidentifier() or name in RESERVED:
            raise SweepError(f"record.functions: {name!r} is not a usable name (an identifier, "
                             f"not one of {', '.join(sorted(RESERVED))})")
        functions[name] = _function(fn, f"record.functions.{name}", None)
    return dataclasses.replace(record, functions=functions)


def _check_filters(filters: Any) -> Filters:
    if not isinstance(filters, Filters):
        raise SweepError(f"filters must be a Filters or a table, got {type(filters).__name__}")
    if filters.max_stretch is not None and not (
        isinstance(filters.max_stretch, int | float) and not isinstance(filters.max_stretch, bool)
        and filters.max_stretch >= 0
    ):
        raise SweepError(f"filters.max_stretch must be a number >= 0, got "
                         f"{filters.max_stretch!r}")
    if filters.reject is not None:
        return dataclasses.replace(filters, reject=_function(filters.reject, "filters.reject",
                                                             None))
    return filters


def check_picklable(runs: Sequence[Run]) -> None:
    """Workers in other processes get each run by pickle: a lambda or a function defined inside
    another function cannot travel, so say so now rather than in every run."""
    if not runs:
        return
    first = runs[0]
    for what, fn in [*((f"record.functions.{k}", f) for k, f in first.record.functions.items()),
                     ("filters.reject", first.filters.reject)]:
        if fn is None:
            continue
        try:
            pickle.dumps(fn)
        except (pickle.PicklingError, AttributeError, TypeError) as err:
            raise SweepError(f"{what} cannot be sent to a worker process ({err}); use a "
                             "module-level function or 'module:name'") from None
