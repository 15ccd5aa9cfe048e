"""The demo's keys: one table from key name to viewer command and help text, read by the
glfw window, by scripted ``key`` events and by the help overlay."""

from __future__ import annotations

KEYS: dict[str, tuple[str, str]] = {
    "SPACE": ("toggle_pause", "pause / run"),
    "N": ("single_step", "one step (pauses)"),
    "R": ("reset", "reset the scene"),
    "I": ("next_integrator", "next integrator"),
    "EQUAL": ("more_substeps", "more substeps (+)"),
    "MINUS": ("fewer_substeps", "fewer substeps (-)"),
    "V": ("next_view", "next debug view"),
    "C": ("toggle_self_collision", "self-collision on / off"),
    "O": ("toggle_ssao", "ambient occlusion on / off"),
    "L": ("next_lights", "next light preset"),
    "Q": ("next_tier", "quality tier: full / software"),
    "D": ("toggle_details", "overlay details"),
    "H": ("toggle_help", "this help"),
    "ESCAPE": ("quit", "quit"),
}
"""Key name (as glfw spells it after ``KEY_``) -> (viewer command, help)."""
# Keys 1..9 load the first nine built-in scenes; later ones load by name (`rustcloth demo NAME`).
NUMBER_KEYS = 9
for _k in range(1, NUMBER_KEYS + 1):
    KEYS[str(_k)] = (f"scene_{_k}", "")  # help for these says which scenes exist


def scene_key_help(names: list[str]) -> str:
    """What the number keys load, and the scenes past them that load by name."""
    keyed, rest = names[:NUMBER_KEYS], names[NUMBER_KEYS:]
    text = f"1..{len(keyed)}: " + ", ".join(keyed)
    return text + (f"; by name (rustcloth demo NAME): {', '.join(rest)}" if rest else "")

ALIASES = {"KP_ADD": "EQUAL", "KP_SUBTRACT": "MINUS", "PLUS": "EQUAL", "+": "EQUAL",
           "-": "MINUS", "ESC": "ESCAPE"}


def command_for(key: str) -> str | None:
    """The viewer command a key name runs, or None for a key that does nothing."""
    name = key.upper()
    name = ALIASES.get(name, name)
    entry = KEYS.get(name)
    return entry[0] if entry else None
