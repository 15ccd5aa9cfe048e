"""Feeds hostile values to every entry point that takes a scene or a state, in a process of its
own, so that a crash (a stack overflow, an abort) ends this process and fails the test that ran
it instead of ending the test run.

``python hostile_worker.py`` reads a JSON list of cases on standard input and prints one line
per case, ``<index> <outcome>``, flushed before the next case starts: the parent reads which
case was running when a crash came. A case is ``[entry, key, recipe]``:

- ``entry``: ``Scene``, ``from_dict``, ``from_toml_str``, ``Simulation``, ``set_state``,
  ``pickle`` (``pickle.loads`` of a crafted simulation) or ``sweep`` (a sweep description
  expanded into its runs);
- ``key``: a dotted scene key (``gravity``, ``cloth.nx``) or, for the state entries, a state
  key (``accumulator``, ``watchdog.hold``, ``scene.gravity``);
- ``recipe``: the value, built by :func:`build`.

The outcome is ``accepted``, ``refused <Exception> <parameter>`` for a package error naming a
parameter, or ``WRONG <Exception>: <message>`` for anything else (a bare Python error, an error
without the parameter, a refused input that changed the simulation).
"""

from __future__ import annotations

import copyreg
import json
import math
import os
import pickle
import struct
import sys
import warnings
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

import rustcloth  # noqa: E402
from conftest import state_differences  # noqa: E402
from rustcloth.errors import RustclothError, StabilityWarning  # noqa: E402


def build(recipe: list[Any]) -> Any:
    """A value from a recipe: ``["nest", depth, leaf]`` (a list nested ``depth`` deep around
    ``leaf``), ``["table", depth]`` (tables nested that deep), ``["int", text]``,
    ``["float", text]`` (``"inf"``, ``"nan"``, ``"1e308"``), ``["list", n, leaf]``,
    ``["str", n]``, ``["array", n]`` (an ``(n, 3)`` float array) or ``["plain", value]``."""
    kind = recipe[0]
    if kind == "nest":
        value = recipe[2]
        for _ in range(recipe[1]):
            value = [value]
        return value
    if kind == "table":
        value = {}
        for _ in range(recipe[1]):
            value = {"a": value}
        return value
    if kind == "int":
        return int(recipe[1])
    if kind == "float":
        return float(recipe[1])
    if kind == "list":
        return [recipe[2]] * recipe[1]
    if kind == "str":
        return "x" * recipe[1]
    if kind == "array":
        return np.full((recipe[1], 3), 0.5)
    return recipe[1]


def _nested(key: str, value: Any) -> dict[str, Any]:
    """``{"a": {"b": value}}`` for the key ``a.b``."""
    parts = key.split(".")
    out: dict[str, Any] = {parts[-1]: value}
    for part in reversed(parts[:-1]):
        out = {part: out}
    return out


def _toml(key: str, recipe: list[Any]) -> str:
    """TOML text setting ``key`` to the recipe's value: nesting is written out as brackets, so
    that the text itself is as deep as the value."""
    if recipe[0] == "nest":
        inner = json.dumps(recipe[2])
        return f"{key} = " + "[" * recipe[1] + inner + "]" * recipe[1]
    if recipe[0] == "table":
        return f"{key} = " + "{ a = " * recipe[1] + "{}" + " }" * recipe[1]
    value = build(recipe)
    if isinstance(value, float) and not math.isfinite(value):
        text = "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    elif isinstance(value, np.ndarray):
        text = json.dumps(value.tolist())
    else:
        text = json.dumps(value)
    return f"{key} = {text}"


def _set(state: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    for part in parts[:-1]:
        state = state[part]
    state[parts[-1]] = value


SENTINEL = "hostile-worker-sentinel"


def _crafted_pickle(state: dict[str, Any], recipe: list[Any]) -> bytes:
    """A pickle that makes ``pickle.loads`` call ``Simulation.__setstate__(state)``, as a
    pickle written by a hostile hand would. Deep nesting is written as opcodes (Python's own
    pickler recurses per level, and on 3.13 stops near 10 000 whatever the recursion limit):
    the value at the sentinel is replaced by the recipe's bytes, which the unpickler reads
    without recursing."""

    class Crafted:
        def __reduce__(self) -> Any:
            return (copyreg._reconstructor, (rustcloth.Simulation, object, None), state)

    # Protocol 2: no frames, whose lengths the replacement would break.
    data = pickle.dumps(Crafted(), protocol=2)
    if recipe[0] not in ("nest", "table"):
        return data
    marker = _opcodes(SENTINEL)
    assert data.count(marker) == 1
    depth = recipe[1]
    if recipe[0] == "nest":
        deep = b"]" * depth + _opcodes(recipe[2]) + b"a" * depth  # EMPTY_LIST ... APPEND
    else:
        deep = (b"}" + _opcodes("a")) * depth + b"}" + b"s" * depth  # EMPTY_DICT ... SETITEM
    return data.replace(marker, deep)


def _opcodes(value: str | float | bool) -> bytes:
    """The pickle opcodes that push `value`, without the memo entry the pickler would add."""
    if isinstance(value, bool):
        return b"\x88" if value else b"\x89"  # NEWTRUE, NEWFALSE
    if isinstance(value, str):
        text = value.encode()
        return b"X" + struct.pack("<I", len(text)) + text  # BINUNICODE
    return b"G" + struct.pack(">d", float(value))  # BINFLOAT


def run_case(entry: str, key: str, recipe: list[Any]) -> str:
    sim = None
    before = None
    try:
        if entry == "Scene":
            rustcloth.Scene(**_nested(key, build(recipe)))
        elif entry == "from_dict":
            rustcloth.Scene.from_dict(_nested(key, build(recipe)))
        elif entry == "from_toml_str":
            rustcloth.Scene.from_toml_str(_toml(key, recipe))
        elif entry == "Simulation":
            rustcloth.Simulation(_nested(key, build(recipe)))
        elif entry in ("set_state", "pickle"):
            sim = rustcloth.Simulation("hanging")
            sim.step(3)
            before = sim.get_state()
            state = sim.get_state()
            _set(state, key, build(recipe))
            if entry == "set_state":
                sim.set_state(state)
            else:
                if recipe[0] in ("nest", "table"):
                    _set(state, key, SENTINEL)
                pickle.loads(_crafted_pickle(state, recipe))
        elif entry == "sweep":
            from rustcloth.sweep import Sweep

            # Expanding checks every run's scene; nothing is run.
            sweep = Sweep.from_dict({"base": "hanging", "steps": 1,
                                     "grid": {key: [build(recipe)]}})
            sweep.points()
        else:
            raise AssertionError(f"unknown entry {entry}")
    except RustclothError as err:
        parameter = getattr(err, "parameter", None)
        if sim is not None and before is not None:
            changed = state_differences(sim.get_state(), before)
            if changed:
                return f"WRONG {type(err).__name__} changed {changed[0]}"
        if parameter is None and entry != "sweep":
            return f"WRONG {type(err).__name__} without a parameter: {str(err)[:120]}"
        return f"refused {type(err).__name__} {parameter}"
    except ValueError as err:
        # The sweep's own SweepError (a ValueError) names the key in its message.
        if entry == "sweep":
            return f"refused {type(err).__name__} -"
        return f"WRONG {type(err).__name__}: {str(err)[:120]}"
    except Exception as err:
        return f"WRONG {type(err).__name__}: {str(err)[:120]}"
    return "accepted"


def main() -> None:
    warnings.simplefilter("ignore", StabilityWarning)
    cases = json.load(sys.stdin)
    for i, (entry, key, recipe) in enumerate(cases):
        print(i, "started", flush=True)
        print(i, run_case(entry, key, recipe), flush=True)


if __name__ == "__main__":
    main()
