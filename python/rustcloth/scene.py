"""Scenes: what a simulation simulates, as plain data.

A :class:`Scene` is built from keyword arguments, a dict or a TOML file with the same keys. The
Rust core owns the schema: it fills in defaults and validates every value, so a scene that
exists is a scene that runs. See the README for every key, its unit and default.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import _core


def _plain(value: Any) -> Any:
    """numpy arrays and scalars as Python lists and numbers, the types the core reads."""
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value


class Scene:
    """A validated scene description.

    >>> scene = Scene(dt=0.002, cloth={"nx": 16, "ny": 16, "pins": ["top_edge"]})
    >>> scene.cloth["k_structural"]
    500.0

    Unknown keys, values of the wrong type and values out of range raise
    :class:`~rustcloth.errors.ParameterError` (a ``ValueError``) or
    :class:`~rustcloth.errors.ParameterTypeError` (a ``TypeError``) naming the key.
    """

    __slots__ = ("_data",)

    def __init__(self, **settings: Any) -> None:
        self._data: dict[str, Any] = _core.normalize_scene(_plain(settings))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scene:
        """A scene from a dict with the keys of the TOML schema."""
        if not isinstance(data, Mapping):
            raise TypeError(f"data must be a mapping, got {type(data).__name__}")
        return cls(**dict(data))

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> Scene:
        """A scene from a TOML file."""
        with open(path, encoding="utf-8") as f:
            return cls.from_toml_str(f.read())

    @classmethod
    def from_toml_str(cls, text: str) -> Scene:
        """A scene from TOML text."""
        scene = cls.__new__(cls)
        scene._data = _core.scene_from_toml(text)
        return scene

    def to_dict(self) -> dict[str, Any]:
        """Every key with its value (defaults included); ``Scene.from_dict`` round-trips it."""
        return copy.deepcopy(self._data)

    def to_toml(self) -> str:
        """The scene as a TOML document; ``Scene.from_toml_str`` round-trips it."""
        return _core.scene_to_toml(self._data)

    def replace(self, **changes: Any) -> Scene:
        """A copy with some keys changed. A dict given for ``cloth`` or ``floor`` is merged into
        the existing table, so ``scene.replace(cloth={"nx": 64})`` keeps the other cloth keys."""
        data = self.to_dict()
        for key, value in changes.items():
            current = data.get(key)
            if isinstance(value, Mapping) and isinstance(current, dict):
                current.update(value)
            else:
                data[key] = value
        return Scene.from_dict(data)

    def __getattr__(self, name: str) -> Any:
        try:
            return copy.deepcopy(self._data[name])
        except KeyError:
            raise AttributeError(f"Scene has no key {name!r}") from None

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and self._data == other._data

    def __hash__(self) -> int:
        return hash(self.to_toml())

    def __repr__(self) -> str:
        cloth = self._data["cloth"]
        extras = []
        if self._data["floor"] is not None:
            extras.append("floor")
        if self._data["spheres"]:
            extras.append(f"{len(self._data['spheres'])} sphere(s)")
        return (
            f"Scene({cloth['nx']}x{cloth['ny']} cloth, {self._data['integrator']}, "
            f"dt={self._data['dt']:g}" + "".join(f", {e}" for e in extras) + ")"
        )


def scenes() -> list[str]:
    """Names of the built-in scenes."""
    return list(_core.builtin_scenes())


def load_scene(name: str) -> Scene:
    """The built-in scene ``name`` (see :func:`scenes`)."""
    return Scene.from_dict(_core.builtin_scene(name))
