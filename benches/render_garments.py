"""Regenerates docs/screenshot_garments.png (the shirt and the skirt on the mannequin after 4 s,
side by side) and docs/garments.gif (the shirt sewn, its first 2.5 s), by the headless
renderer (`rustcloth render`, offscreen through EGL). About a minute on two shared cores.

    python benches/render_garments.py [--out docs]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image
from rustcloth.viewer.headless import write_gif

SIZE = "480x600"
GIF_SIZE = "320x400"


def render(scene: str, out: Path, frames: int, fps: float, size: str) -> list[Path]:
    """Renders `frames` frames of `scene` at `fps` into `out`; the PNGs, in order."""
    subprocess.run([sys.executable, "-m", "rustcloth", "render", scene, "--frames", str(frames),
                    "--fps", str(fps), "--size", size, "--out", str(out)], check=True)
    return sorted(out.glob("frame_*.png"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        # 4 s at 15 frames a second: the last frame is at t = 4 s.
        last = [Image.open(render(name, Path(tmp) / name, 61, 15.0, SIZE)[-1]).convert("RGB")
                for name in ("shirt", "skirt")]
        width, height = last[0].size
        both = Image.new("RGB", (2 * width, height))
        for k, image in enumerate(last):
            both.paste(image, (k * width, 0))
        both.save(args.out / "screenshot_garments.png")
        frames = render("shirt", Path(tmp) / "gif", 31, 12.0, GIF_SIZE)
        write_gif(args.out / "garments.gif",
                  [np.asarray(Image.open(p).convert("RGB")) for p in frames], 12.0)
    print(f"wrote {args.out / 'screenshot_garments.png'} and {args.out / 'garments.gif'}")


if __name__ == "__main__":
    main()
