"""Fit a cloth's bending stiffness and damping to a target drape's silhouette, by a sweep.

    python examples/fit_drape.py                 # 45 runs on this machine's cores
    python examples/fit_drape.py --backend ray   # the same runs as Ray tasks
    python -m rustcloth sweep examples/fit_drape.toml --out fit_drape   # the same, from TOML

A cloth is dropped onto a sphere (the built-in "drape" scene at 24 x 24). The target is the
same cloth with parameters the fit is not told (k_bend = 10 N/m, damping = 0.025 N s/m); its
"measurement" is its silhouette seen from the front (a 48 x 48 mask of what the cloth covers
in the x-y plane) at 0.5, 0.75, ... 2 s. Each run of the sweep records the same silhouettes
with a record function, computed in the worker, so only 9 small masks per run come back. The
error of a run is 1 - IoU (intersection over union) of its masks and the target's, averaged
over the frames; the script prints the best runs and plots the error surface over (k_bend,
damping) to fit_drape.png (matplotlib: pip install 'rustcloth[study]').

Copy it and change TARGET, the grid and silhouette() for your own data. The sweep is
resumable: run it again and it only reads the results back.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import rustcloth
from rustcloth.sweep import Record, Sweep, run_sweep

TARGET = {"k_bend": 10.0, "damping": 0.025}
RES = 48  # silhouette pixels per side
WINDOW = ((-1.0, 1.0), (0.0, 1.3))  # x and y extent of the silhouette, m
EVERY = 250  # steps between frames (dt = 1 ms)
SECONDS = 2.0
FIRST_FRAME_S = 0.5  # earlier frames see the falling sheet edge-on: not compared
# Barycentric sample points on each triangle, dense enough for pixels larger than a triangle.
_U, _V = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))
_KEEP = _U + _V <= 1
SAMPLES = np.stack([_U[_KEEP], _V[_KEEP]], axis=1)


def make_scene(k_bend: float, damping: float) -> rustcloth.Scene:
    """The drape scene at 24 x 24 with the cloth's mass kept at 0.9 kg and a little air drag
    so it settles; k_bend and damping are the fit's parameters."""
    scene = rustcloth.load_scene("drape").to_dict()
    cloth = scene["cloth"]
    cloth.pop("particle_mass", None)
    cloth.update(nx=24, ny=24, mass=0.9, k_bend=k_bend, damping=damping)
    scene["air_drag"] = 0.002
    return rustcloth.Scene.from_dict(scene)


def silhouette(sim: rustcloth.Simulation) -> np.ndarray:
    """What the cloth covers seen from the front: a (RES, RES) bool mask of the x-y plane,
    row 0 at the bottom, rasterised by marking the pixel under each sample point of each
    triangle of the mesh."""
    x = sim.positions[:, :2]
    tri = sim.triangles
    a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    points = (a[:, None] + SAMPLES[None, :, :1] * (b - a)[:, None]
              + SAMPLES[None, :, 1:] * (c - a)[:, None]).reshape(-1, 2)
    (x0, x1), (y0, y1) = WINDOW
    i = np.floor((points[:, 0] - x0) / (x1 - x0) * RES).astype(int)
    j = np.floor((points[:, 1] - y0) / (y1 - y0) * RES).astype(int)
    inside = (i >= 0) & (i < RES) & (j >= 0) & (j < RES)
    mask = np.zeros((RES, RES), dtype=bool)
    mask[j[inside], i[inside]] = True
    return mask


def target_silhouettes() -> np.ndarray:
    """The target's masks at the frames every run records (steps 0, EVERY, ...)."""
    sim = rustcloth.Simulation(make_scene(**TARGET))
    masks = [silhouette(sim)]
    while sim.steps < round(SECONDS / sim.dt):
        sim.step(EVERY)
        masks.append(silhouette(sim))
    return np.array(masks)


def error(masks: np.ndarray, target: np.ndarray, times: np.ndarray) -> float:
    """1 - IoU of two stacks of masks, averaged over the frames from FIRST_FRAME_S on."""
    use = times >= FIRST_FRAME_S - 1e-9
    inter = (masks[use] & target[use]).sum(axis=(1, 2))
    union = np.maximum((masks[use] | target[use]).sum(axis=(1, 2)), 1)
    return float(np.mean(1.0 - inter / union))


def the_sweep(quick: bool) -> Sweep:
    k_bend = np.geomspace(2.0, 50.0, 5 if quick else 9).round(3)
    damping = np.geomspace(0.005, 0.08, 3 if quick else 5).round(4)
    return Sweep(
        scene_fn=make_scene,
        grid={"k_bend": k_bend, "damping": damping},
        seconds=SECONDS,
        record=Record(every=EVERY, positions=False, final_mesh=True,
                      functions={"silhouette": silhouette}),
    )


def plot(k_bend: np.ndarray, damping: np.ndarray, errors: np.ndarray, best: dict,
         path: str) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("no plot: matplotlib is not installed (pip install 'rustcloth[study]')")
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    mesh = ax.pcolormesh(k_bend, damping, errors.T, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="silhouette error, 1 - IoU (mean over frames)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(k_bend, [f"{k:.3g}" for k in k_bend])
    ax.set_yticks(damping, [f"{c:.3g}" for c in damping])
    ax.minorticks_off()
    ax.plot(TARGET["k_bend"], TARGET["damping"], "r*", ms=14, label="target (hidden)")
    ax.plot(best["k_bend"], best["damping"], "o", mfc="none", mec="orange", ms=12, mew=2,
            label="best run")
    ax.set_xlabel("k_bend [N/m]")
    ax.set_ylabel("damping [N s/m]")
    ax.set_title("Drape silhouette error over the sweep")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"error surface: {path}")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--out", default="fit_drape", help="sweep output folder")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="where the runs go")
    parser.add_argument("--quick", action="store_true", help="a 5 x 3 grid instead of 9 x 5")
    parser.add_argument("--plot", default="fit_drape.png", help="error surface image")
    args = parser.parse_args(argv)

    sweep = the_sweep(args.quick)
    result = run_sweep(sweep, args.out, args.backend)
    print(f"{len(result.records)} runs ({result.ran} ran now) in {result.wall_s:.1f} s: "
          f"{result.counts}")
    target = target_silhouettes()
    k_values = sorted({r["params"]["k_bend"] for r in result.records})
    c_values = sorted({r["params"]["damping"] for r in result.records})
    errors = np.full((len(k_values), len(c_values)), np.nan)
    for record in result.ok():
        arrays = result.load(record)
        p = record["params"]
        errors[k_values.index(p["k_bend"]), c_values.index(p["damping"])] = error(
            arrays["silhouette"], target, arrays["time"])
    i, j = np.unravel_index(np.nanargmin(errors), errors.shape)
    best = {"k_bend": k_values[i], "damping": c_values[j]}
    print(f"target: k_bend = {TARGET['k_bend']:g}, damping = {TARGET['damping']:g}")
    print(f"best:   k_bend = {best['k_bend']:g}, damping = {best['damping']:g}, "
          f"error {errors[i, j]:.4f}")
    print("\nerror by k_bend (best damping for each): the silhouette pins k_bend;")
    print("along damping the surface is a shallow valley (a settled drape hardly depends on it)")
    for k, row in zip(k_values, errors, strict=True):
        damping = c_values[int(np.nanargmin(row))]
        print(f"  k_bend {k:7.3f}: {np.nanmin(row):.4f} (damping {damping:g})")
    plot(np.array(k_values), np.array(c_values), errors, best, args.plot)
    return 0


if __name__ == "__main__":  # needed: local workers import this file to find silhouette()
    sys.exit(main(sys.argv[1:]))
