"""The strict readers of :class:`~rustcloth.Simulation`'s arguments.

Each reads one argument as the compiled core takes it (a float, an int, a tuple of floats, a
numpy array it can read without a copy) or raises the :mod:`rustcloth.errors` exception that
names the parameter and the bad value. They are strict on purpose: a bool is not a number
(``True`` would be 1), bytes are not a vector (``b"abc"`` would be ``(97, 98, 99)``), a complex
number is not real (its imaginary part would be dropped), and a count given as ``2.0`` is
refused. Values (finite, in range) are checked by the core, with the same names.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from typing import Any, NoReturn

import numpy as np

from . import _core
from .errors import ParameterError, ParameterTypeError, ParticleIndexError

I64_MAX = 2**63 - 1
# The smallest magnitude float32 rounds to infinity: float32's largest value plus half an ulp.
F32_OVERFLOW = 2.0**128 - 2.0**103

Vec = tuple[float, ...]


def type_error(name: str, message: str) -> NoReturn:
    raise ParameterTypeError(f"{name}: {message}", name)


def value_error(name: str, message: str) -> NoReturn:
    raise ParameterError(f"{name}: {message}", name)


def text_of(value: object, show: Any = str) -> str:
    """``str(value)`` (or ``show(value)``), or ``""`` if it fails: a message never raises."""
    try:
        return str(show(value))
    except Exception:
        return ""


def shown(value: object) -> str:
    """``repr(value)``, shortened for messages."""
    text = text_of(value, repr)
    return text if len(text) <= 60 else text[:57] + "..."


def dtype_kind(value: object) -> str | None:
    """The numpy dtype kind (``'f'``, ``'b'``, ``'c'``, ...) of a numpy scalar or array."""
    try:
        kind = value.dtype.kind  # type: ignore[attr-defined]
    except Exception:
        return None
    return kind if isinstance(kind, str) else None


def is_bool(value: object) -> bool:
    """Python's bool or numpy's (a scalar, not a ``bool`` subclass, or a 0-d array), which
    would otherwise convert to 0 or 1."""
    return (
        isinstance(value, bool)
        or type(value).__name__ in ("bool", "bool_")
        or dtype_kind(value) == "b"
    )


def got(value: object) -> str:
    """The type and value for messages: ``bool True``, ``str 'x'``."""
    kind = "bool" if is_bool(value) else type(value).__name__
    return f"{kind} {shown(value)}"


def real(value: object, name: str) -> float:
    """A real number: an ``int``, a ``float``, a numpy scalar or anything with ``__float__``
    or ``__index__``; never a bool, a string, bytes or a complex number."""
    if type(value) is float:
        return value
    if is_bool(value):
        type_error(name, f"must be a number, got {got(value)}")
    if isinstance(value, str | bytes | bytearray | complex) or dtype_kind(value) == "c":
        type_error(name, f"must be a real number, got {got(value)}")
    kind = type(value)
    if not (hasattr(kind, "__float__") or hasattr(kind, "__index__")):
        type_error(name, f"must be a number, got {got(value)}")
    try:
        return float(value)  # type: ignore[arg-type]
    except OverflowError:
        value_error(name, f"{shown(value)} is too large for a float")
    except Exception:
        type_error(name, f"must be a number, got {got(value)}")


def integer(value: object, name: str) -> int:
    """A whole number: an ``int`` or a numpy integer, never a bool or a float (not even
    ``2.0``: a count given as a float is usually a mistake). Values outside 64 bits are
    value errors."""
    if is_bool(value):
        type_error(name, f"must be an integer, got {got(value)}")
    try:
        n = operator.index(value)  # type: ignore[arg-type]
    except Exception:
        type_error(name, f"must be an integer, got {got(value)}")
    if not -I64_MAX - 1 <= n <= I64_MAX:
        value_error(name, f"{shown(value)} is out of range")
    return n


def count(value: object, name: str) -> int:
    """An integer ``>= 0``."""
    n = value if type(value) is int and 0 <= value <= I64_MAX else integer(value, name)
    if n < 0:
        value_error(name, f"must be an integer >= 0, got {n}")
    return n


def text(value: object, name: str) -> str:
    """A ``str``."""
    if not isinstance(value, str):
        type_error(name, f"must be a string, got {got(value)}")
    return value


def index(value: object, name: str) -> int:
    """A particle (or collider) index: any integer but a bool. One beyond 64 bits is passed
    on as the largest 64-bit integer, which the core refuses as out of range."""
    if type(value) is int and -I64_MAX - 1 <= value <= I64_MAX:
        return value
    if isinstance(value, bool):
        type_error(name, f"must be an integer index, got {text_of(value)}")
    try:
        n = operator.index(value)  # type: ignore[arg-type]
    except Exception:
        type_error(name, f"must be an integer index, got {type(value).__name__} {text_of(value)}")
    return n if -I64_MAX - 1 <= n <= I64_MAX else I64_MAX


def floats(value: object, name: str, n: int) -> Vec:
    """``n`` real numbers from a sequence (or 1-D numeric array) of ``n``. A string, bytes, a
    dict (its keys) or a set (any order) is not a sequence of numbers."""
    if type(value) in (tuple, list) and len(value) == n:  # type: ignore[arg-type]
        if all(type(c) is float for c in value):  # type: ignore[attr-defined]
            return tuple(value)  # type: ignore[arg-type]
    if isinstance(value, np.ndarray):
        sequence = value.ndim == 1 and value.dtype.kind in "fiu"
    else:
        sequence = isinstance(value, Sequence) and not isinstance(value, str | bytes | bytearray)
    if not sequence:
        type_error(name, f"must be a sequence of {n} numbers, got {type(value).__name__} "
                         f"{shown(value)}")
    items = list(value)  # type: ignore[call-overload]
    if len(items) != n:
        value_error(name, f"must have {n} components, got {len(items)}")
    return tuple(real(c, f"{name}[{k}]") for k, c in enumerate(items))


def direction(value: object, name: str) -> Vec:
    """A direction: a 3-vector scaled to unit length in float64 before the core takes it in
    float32, so that a short one such as ``(0, 0, 1e-300)`` keeps its direction. One that is
    zero, or not finite in float32, is passed on as it is for the core to refuse."""
    v = floats(value, name, 3)
    largest = max(abs(c) for c in v)
    if not all(abs(c) < F32_OVERFLOW for c in v) or largest == 0.0:
        return v
    # Scaled by the largest component first: the squared length of (0, 0, 1e-200) underflows.
    x, y, z = (c / largest for c in v)
    inverse = 1.0 / math.sqrt(x * x + y * y + z * z)
    return (x * inverse, y * inverse, z * inverse)


def rows(value: object, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A float32 or float64 numpy array of ``shape``, in the machine's byte order (a
    big-endian array is as valid as any)."""
    expected = f"({shape[0]},)" if len(shape) == 1 else f"({shape[0]}, {shape[1]})"
    if not isinstance(value, np.ndarray):
        type_error(name, f"must be a numpy array of shape {expected}, got {type(value).__name__}")
    if value.shape != shape:
        value_error(name, f"must have shape {expected}, got [{', '.join(map(str, value.shape))}]")
    if value.dtype.kind != "f" or value.dtype.itemsize not in (4, 8):
        type_error(name, f"must have dtype float32 or float64, got {value.dtype}")
    return value if value.dtype.isnative else value.astype(value.dtype.newbyteorder("="))


def indices(value: np.ndarray, particles: int) -> np.ndarray:
    """``pin_many``'s indices: a 1-D integer array (of any dtype when empty), as int64. The
    core checks each against the particles."""
    if value.ndim != 1:
        value_error("indices", f"must be 1-D, got shape {value.shape}")
    if len(value) and value.dtype.kind not in "iu":
        type_error("indices", f"must hold integers, got dtype {value.dtype}")
    if len(value) and value.dtype.kind == "u" and int(value.max()) > I64_MAX:
        message = f"indices: index {int(value.max())} is out of range for {particles} particles"
        raise ParticleIndexError(message, "indices", I64_MAX)
    return value.astype(np.int64)


def stroke(value: object) -> np.ndarray:
    """A stroke: an ``(M, 2, 3)`` float array, read by the core in one pass, or any sequence
    of ``(origin, direction)`` pairs, each named ``rays[k]`` in errors."""
    if isinstance(value, np.ndarray) and value.ndim == 3 and value.shape[1:] == (2, 3):
        if value.dtype in (np.float32, np.float64) and value.dtype.isnative:
            return value
    if isinstance(value, str | bytes):
        type_error("rays", f"must be a sequence of (origin, direction) pairs, got {text_of(value)}")
    try:
        items = iter(value)  # type: ignore[call-overload]
    except TypeError:
        type_error("rays", f"must be a sequence of (origin, direction) pairs, got {text_of(value)}")
    rays = [ray(item, f"rays[{k}]") for k, item in enumerate(items)]
    return np.array(rays, dtype=np.float64).reshape(len(rays), 2, 3)


def ray(value: Any, name: str) -> tuple[Vec, Vec]:
    """One ray of a stroke: a pair ``(origin, direction)``."""
    pair = "must be an (origin, direction) pair"
    try:
        size = len(value)
    except Exception:
        type_error(name, f"{pair}, got {text_of(value)}")
    if size != 2:
        value_error(name, f"{pair}, got {size} items")
    return floats(value[0], f"{name}.origin", 3), direction(value[1], f"{name}.direction")


def scene_data(value: object, name: str = "", depth: int = 0) -> Any:
    """A scene dict (plain dicts, lists, numbers, strings, numpy arrays) as the core reads it
    into the TOML value it also parses files into: ``None`` values dropped (absent), tuples as
    lists, arrays of real numbers as float64 or int64 arrays (read by the core in one pass,
    never as Python lists: a mesh of a million triangles), other arrays as their ``tolist()``,
    so that the core's errors name their offending element as a list's. Refuses by name what
    TOML cannot hold, and nesting deeper than ``_core.MAX_NESTING`` (an array's numbers lie
    ``ndim`` levels below it), before recursing into it. ``depth``: how many lists and tables
    hold ``value``."""
    where = name or "scene"
    deepest = depth + value.ndim if isinstance(value, np.ndarray) else depth
    if deepest > _core.MAX_NESTING:
        value_error(where, f"lists and tables nest at most {_core.MAX_NESTING} deep in a scene")
    if isinstance(value, dict):
        table = {}
        for key, item in value.items():
            if not isinstance(key, str):
                type_error(where, f"keys must be strings, got {text_of(key, repr)}")
            if item is not None:
                table[key] = scene_data(item, f"{name}.{key}" if name else key, depth + 1)
        return table
    if isinstance(value, bool | float | str):
        return value
    if isinstance(value, int):
        if not -I64_MAX - 1 <= value <= I64_MAX:
            value_error(where, f"{text_of(value)} does not fit a 64-bit integer")
        return value
    if isinstance(value, list | tuple):
        # Numbers, and lists of numbers (a mesh's rows as lists: a million of them), are taken
        # as they are, without the walk's call each, where they nest shallow enough.
        leaf, row = depth + 1 <= _core.MAX_NESTING, depth + 2 <= _core.MAX_NESTING
        return [x if (leaf and _number(x)) or (row and type(x) is list and all(map(_number, x)))
                else scene_data(x, f"{where}[{i}]", depth + 1) for i, x in enumerate(value)]
    if isinstance(value, np.ndarray):
        kind, size = value.dtype.kind, value.dtype.itemsize
        if kind == "f":
            return value.astype(np.float64, copy=False)
        if kind == "i" or (kind == "u" and size <= 4):
            return value.astype(np.int64, copy=False)
        return scene_data(value.tolist(), name, depth)
    type_error(where, f"unsupported value of type {type(value).__name__}: {text_of(value)}")


def _number(x: object) -> bool:
    """A float or an int that fits 64 bits (not a bool, nor a subclass): a plain leaf."""
    return type(x) is float or (type(x) is int and -I64_MAX - 1 <= x <= I64_MAX)


def state_array(value: object, name: str, dtype: str, shape: Sequence[int]) -> np.ndarray:
    """Exactly a ``dtype`` array of ``shape``, ``(n,)`` or ``(n, 3)``, for a saved state: a state
    is bits, and another dtype would be another state."""
    shape = tuple(shape)
    expected = f"({shape[0]},)" if len(shape) == 1 else f"({shape[0]}, {shape[1]})"
    if not (isinstance(value, np.ndarray) and value.dtype == dtype and value.ndim == len(shape)):
        type_error(name, f"must be a {dtype} array of shape {expected}")
    if value.shape != shape:
        got = f"({value.shape[0]},)" if len(shape) == 1 else f"[{', '.join(map(str, value.shape))}]"
        value_error(name, f"must have shape {expected}, got {got}")
    return value


def state_bools(given: Any, read: object, name: str) -> None:
    """Refuses in a saved state what the core's serde reader takes and the strict readers do
    not: a bool where a number goes (``True`` as 1), anything but a bool where a bool goes
    (serde takes any value's truth). ``read`` is what was read, back as Python values: its
    shape leads the walk, and keys it filled in with their defaults are not looked for."""
    if isinstance(read, dict):
        for key, value in read.items():
            try:
                item = given[key]
            except Exception:
                continue
            state_bools(item, value, f"{name}.{key}")
    elif isinstance(read, list | tuple):
        for k, value in enumerate(read):
            state_bools(given[k], value, f"{name}[{k}]")
    elif isinstance(read, bool) != (isinstance(given, bool) or dtype_kind(given) == "b"):
        if isinstance(read, bool):
            type_error(name, f"must be a bool, got {given}")
        type_error(name, f"must be a number, got bool {given}")


def state_items(value: object, name: str, n: int) -> list[Any]:
    """Exactly ``n`` items of a sequence, for a saved state."""
    try:
        iterator = iter(value)  # type: ignore[call-overload]
    except Exception:
        type_error(name, f"must be a sequence, got {value}")
    items = list(iterator)
    if len(items) != n:
        value_error(name, f"must have {n} items, got {len(items)}")
    return items
