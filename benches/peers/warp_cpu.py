"""Warp started on the CPU device the way both newton contact peers need it."""

from __future__ import annotations

import tempfile

import warp as wp


def start_warp_on_cpu(cold: bool) -> None:
    """Initialises Warp quietly on the CPU; ``cold`` points its kernel cache at an empty folder,
    so that every kernel is compiled (the first-run cost a user pays)."""
    if cold:
        wp.config.kernel_cache_dir = tempfile.mkdtemp(prefix="warp-cold-")
    wp.config.quiet = True
    wp.init()
    wp.set_device("cpu")
