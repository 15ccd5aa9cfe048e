"""Contact against newton (issue 13), side by side in one run: the twist (newton's own
``example_cloth_twist`` against rustcloth's ``twist`` with ``[self_collision]``, 50 x 50) and mesh
contact (a 128 x 128 cloth on a 20480-triangle closed mesh, newton's soft contacts against
rustcloth's mesh collider). Writes ``benches/peers/contact_results.json`` and
``docs/peers_contact.md``.

    bash benches/peers/setup.sh                              # the peers venv (once)
    .venv-peers/bin/python benches/peers/contact.py          # everything (about 15 minutes)
    .venv-peers/bin/python benches/peers/contact.py --quick  # a few frames of each
    .venv-peers/bin/python benches/peers/contact.py --report-only
    .venv-peers/bin/python benches/peers/contact.py --only twist-rustcloth-2

Every peer runs in its own process, one after the other (rustcloth with ``RAYON_NUM_THREADS``
1 and 2; Warp's CPU kernels run on one thread). The newton runs use Warp's kernel cache as the
earlier runs left it; the ``*-cold`` runs point Warp at an empty cache and report the set-up
and first frame, which then include compiling every kernel. Intersections are counted by
``tri_check.py`` on both peers' positions.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
RESULTS = HERE / "contact_results.json"
DOC = ROOT / "docs" / "peers_contact.md"

TWIST_TARGET_MS = 6.5  # per 1/60 s frame, intersection-free (newton's figure on an RTX 5090)
MESH_TARGET_MS = 1.0  # per substep at 128 x 128 with a 20k-triangle mesh
FAST = ["--steps-per-frame", "2", "--solve-stiffness", "30"]
FAST_LABEL = "rustcloth `twist`, implicit Euler, 2 steps, `solve_stiffness` 30"


def runs(quick: bool) -> list[dict]:
    frames, every = (6, 3) if quick else (180, 30)
    mesh_steps_newton = 5 if quick else 30
    mesh_steps_rust = 20 if quick else 200
    tw = ["--frames", str(frames), "--every", str(every)]
    return [
        {"key": "twist-newton", "script": "impl_newton_twist.py", "args": tw, "threads": 1},
        {"key": "twist-rustcloth-2", "script": "impl_rustcloth_twist.py", "args": tw,
         "threads": 2},
        {"key": "twist-rustcloth-1", "script": "impl_rustcloth_twist.py", "args": tw,
         "threads": 1},
        # As the built-in scenes step: implicit Euler at 2 steps a frame, the pairs ahead of
        # each step held inside its solve (docs/contact.md, "Self-contact inside implicit
        # Euler's solve").
        {"key": "twist-rustcloth-fast-2", "script": "impl_rustcloth_twist.py",
         "args": [*tw, *FAST], "threads": 2},
        {"key": "twist-rustcloth-fast-1", "script": "impl_rustcloth_twist.py",
         "args": [*tw, *FAST], "threads": 1},
        {"key": "mesh-newton", "script": "impl_newton_mesh.py",
         "args": ["--steps", str(mesh_steps_newton)], "threads": 1},
        {"key": "mesh-rustcloth-2", "script": "impl_rustcloth_mesh.py",
         "args": ["--steps", str(mesh_steps_rust)], "threads": 2},
        {"key": "mesh-rustcloth-1", "script": "impl_rustcloth_mesh.py",
         "args": ["--steps", str(mesh_steps_rust)], "threads": 1},
        {"key": "twist-newton-cold", "script": "impl_newton_twist.py",
         "args": ["--frames", "2", "--every", "2", "--cold"], "threads": 1},
        {"key": "mesh-newton-cold", "script": "impl_newton_mesh.py",
         "args": ["--steps", "1", "--cold"], "threads": 1},
    ]


def execute(run: dict) -> dict:
    env = {**os.environ, "RAYON_NUM_THREADS": str(run["threads"]), "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, str(HERE / run["script"]), *run["args"]]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=str(ROOT),
                              timeout=3600)
    except subprocess.TimeoutExpired:
        return {"error": "timed out after 3600 s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return {"error": f"exit {proc.returncode}: " + " | ".join(tail)}


# ----- the report --------------------------------------------------------------------------

def fmt(x, spec=".1f", missing="—"):
    return missing if x is None else format(x, spec)


def verdict(ok: bool) -> str:
    return "**met**" if ok else "**missed**"


def runs_dated(r: dict) -> str:
    """Which runs were made when, on which commit of rustcloth: `--only` reruns some."""
    when: dict[tuple[str, str], list[str]] = {}
    for key, v in r.items():
        when.setdefault((v.get("date", "?"), v.get("commit", "?")), []).append(key)
    return "; ".join(f"{', '.join(keys)} on {date} at commit {commit}"
                     for (date, commit), keys in sorted(when.items()))


def report(data: dict) -> str:
    r = data["results"]
    tn, t2, t1 = r.get("twist-newton", {}), r.get("twist-rustcloth-2", {}), r.get(
        "twist-rustcloth-1", {})
    f2, f1 = r.get("twist-rustcloth-fast-2", {}), r.get("twist-rustcloth-fast-1", {})
    mn, m2, m1 = r.get("mesh-newton", {}), r.get("mesh-rustcloth-2", {}), r.get(
        "mesh-rustcloth-1", {})
    cold_t, cold_m = r.get("twist-newton-cold", {}), r.get("mesh-newton-cold", {})
    out = [
        "# Contact against newton",
        "",
        "Generated by `benches/peers/contact.py` from `benches/peers/contact_results.json`; do "
        "not edit by hand. Issue 13: rustcloth's self-collision and mesh collider side by side "
        "with NVIDIA newton on the CPU, in one run.",
        "",
        f"Measured on {data['machine']}: {runs_dated(r)} (rustcloth built release into "
        "`.venv-peers` by `benches/peers/setup.sh`; rebuild with `FORCE=1`), "
        f"{tn.get('version', 'newton ?')}. Each peer ran in its own process, one after the "
        "other; the machine is shared, so the load average at the end of each run is given. "
        "Warp's CPU backend runs a kernel on one thread; rustcloth ran with 2 rayon threads "
        "and with 1 (like for like).",
        "",
        "## Targets",
        "",
        "| target | rustcloth, 2 threads | rustcloth, 1 thread | |",
        "|---|---|---|---|",
    ]
    frames = [s["frame"] for s in t2.get("samples", [])]

    def crossings(v: dict) -> int:
        return max((s["intersections"] for s in v.get("samples", [])), default=-1)

    if t2 and t1:
        ok = t2["ms_per_frame"] <= TWIST_TARGET_MS and crossings(t2) == 0
        out.append(
            f"| twist at 50 x 50 intersection-free, <= {TWIST_TARGET_MS} ms per 1/60 s frame "
            f"| {t2['ms_per_frame']:.1f} ms, {crossings(t2)} crossings at the most "
            f"| {t1['ms_per_frame']:.1f} ms, {crossings(t1)} crossings | {verdict(ok)} |")
    if f2 and f1 and "error" not in f2 and "error" not in f1:
        ok = f2["ms_per_frame"] <= TWIST_TARGET_MS and crossings(f2) == 0
        out.append(
            f"| the same at 2 steps a frame, `solve_stiffness` 30 "
            f"| {f2['ms_per_frame']:.1f} ms, {crossings(f2)} crossings at the most "
            f"| {f1['ms_per_frame']:.1f} ms, {crossings(f1)} crossings | {verdict(ok)} |")
    if m2 and m1:
        ok = m2["collide_ms_per_substep"] <= MESH_TARGET_MS
        out.append(
            f"| mesh contact at 128 x 128, {m2['mesh_triangles']} triangles, <= "
            f"{MESH_TARGET_MS} ms per substep | {m2['collide_ms_per_substep']:.2f} ms "
            f"| {m1['collide_ms_per_substep']:.2f} ms | {verdict(ok)} |")
    out += ["", "## Twist, 50 x 50", "",
            "Wall time per 1/60 s frame, frames 2 to "
            f"{len(t2.get('walls', [])) or '?'} (the first pays for allocations; for newton "
            "also for any kernel not yet in Warp's cache), and the triangle pairs sharing no "
            "vertex that intersect, by `tri_check.py`, every "
            f"{frames[1] - frames[0] if len(frames) > 1 else '?'} frames.", ""]
    header = "| peer | threads | ms/frame mean | median | of which simulation | " + " | ".join(
        f"x@{f}" for f in frames) + " | mean stretch at the end | largest stretch | load |"
    out += [header, "|---|--:|--:|--:|--:|" + "--:|" * len(frames) + "--:|--:|--:|"]
    for label, v in [("newton `example_cloth_twist` (VBD, 10 x 4)", tn),
                     ("rustcloth `twist`, implicit Euler, 10 steps", t2),
                     ("rustcloth `twist`, implicit Euler, 10 steps", t1),
                     (FAST_LABEL, f2), (FAST_LABEL, f1)]:
        if not v or "error" in v:
            out.append(f"| {label} | | {v.get('error', 'not run')} |")
            continue
        by_frame = {s["frame"]: s["intersections"] for s in v["samples"]}
        sim = v.get("step_ms_per_frame", v["ms_per_frame"])
        out.append(
            f"| {label} | {v['threads']} | {v['ms_per_frame']:.1f} | "
            f"{v['ms_per_frame_median']:.1f} | {sim:.1f} | "
            + " | ".join(str(by_frame.get(f, "—")) for f in frames)
            + f" | {v['samples'][-1]['mean_stretch']:.3f} "
            f"| {max(s['max_stretch'] for s in v['samples']):.3f} | {v['load']:.1f} |")
    if t2.get("driver_ms_per_frame") is not None:
        out += ["", f"rustcloth's frame includes its Python driver (`TwistDriver`, 100 `pin` "
                f"calls a step): {t2['driver_ms_per_frame']:.1f} ms of the 2-thread frame; "
                "\"of which simulation\" is the `step()` calls alone. newton's edge rotation "
                "is a kernel inside its captured graph."]
    if t2.get("profile_ms_per_frame"):
        prof = sorted(t2["profile_ms_per_frame"].items(), key=lambda kv: -kv[1])
        out += ["", "rustcloth's passes per frame, 2 threads (`Simulation.profile()`, over the "
                "whole run): " + ", ".join(f"{k} {ms:.1f} ms" for k, ms in prof[:5])
                + f"; {t2.get('pairs_per_substep', 0):.0f} pairs looked at and "
                f"{t2.get('contacts_per_substep', 0):.0f} contacts per substep, "
                f"{100 * t2.get('swept_share', 0):.0f} % of substeps on the swept search."]
    out += ["", "## Mesh contact, 128 x 128 on 20480 triangles", "",
            "The collision pass per substep (newton: `CollisionPipeline.collide`, which makes "
            "the particle-mesh soft contacts; rustcloth: `profile()`'s `colliders` pass, as "
            "`benches/mesh_collider.py` measures it), the rest of the substep, the best of "
            "three slices each.", "",
            "| peer | threads | collision ms/substep | rest of the substep ms | substep dt | "
            "particles within 1 cm of the mesh | load |",
            "|---|--:|--:|--:|--:|--:|--:|"]
    for label, v in [("newton soft contacts, SolverVBD", mn),
                     ("rustcloth mesh collider, symplectic Euler", m2),
                     ("rustcloth mesh collider, symplectic Euler", m1)]:
        if not v or "error" in v:
            out.append(f"| {label} | | {v.get('error', 'not run')} |")
            continue
        out.append(
            f"| {label} | {v['threads']} | {v['collide_ms_per_substep']:.2f} | "
            f"{v['solve_ms_per_substep']:.2f} | {1e3 * v['substep_dt']:.2f} ms | "
            f"{100 * v['contact_share']:.0f} % | {v['load']:.1f} |")
    if mn and m1 and "error" not in mn and "error" not in m1:
        out += ["", f"Thread for thread the collision pass is "
                f"{mn['collide_ms_per_substep'] / m1['collide_ms_per_substep']:.1f}x "
                "faster in rustcloth; newton's examples call `collide` once per frame "
                f"(twist) or once per substep (hanging cloth): once a frame of 10 substeps it "
                f"would be {mn['collide_ms_per_substep'] / 10:.2f} ms a substep, stale in "
                "between."]
    out += ["", "## Warp's kernel compilation", "",
            "Set-up and first frame with an empty kernel cache (`--cold`), against the same "
            "with the cache the other runs left:", "",
            "| newton run | set-up s, cold | first frame s, cold | set-up s, cached | "
            "first frame s, cached |", "|---|--:|--:|--:|--:|"]
    if cold_t and tn and "error" not in cold_t:
        out.append(f"| twist | {cold_t['setup_s']:.1f} | {cold_t['first_frame_s']:.1f} | "
                   f"{tn['setup_s']:.1f} | {tn['first_frame_s']:.1f} |")
    if cold_m and mn and "error" not in cold_m:
        out.append(f"| mesh contact (first substep) | {cold_m['setup_s']:.1f} | "
                   f"{cold_m['first_substep_s']:.1f} | {mn['setup_s']:.1f} | "
                   f"{mn['first_substep_s']:.1f} |")
    out += reading(r)
    out += ["", (HERE / "contact_method.md").read_text().rstrip(), ""]
    return "\n".join(out)


def reading(r: dict) -> list[str]:
    """Sentences computed from the numbers."""
    tn, t1, t2 = r.get("twist-newton"), r.get("twist-rustcloth-1"), r.get("twist-rustcloth-2")
    mn, m1, m2 = r.get("mesh-newton"), r.get("mesh-rustcloth-1"), r.get("mesh-rustcloth-2")
    text = ["", "## Reading", ""]
    if tn and t1 and t2 and not any("error" in v for v in (tn, t1, t2)):
        crossed = [(s["frame"], s["intersections"]) for s in tn["samples"] if s["intersections"]]
        sc = t2.get("profile_ms_per_frame", {}).get("self_collision")
        text.append(
            f"- **Twist.** Thread for thread rustcloth's frame is "
            f"{tn['ms_per_frame'] / t1['ms_per_frame']:.1f}x faster than newton's on this CPU "
            f"({t1['ms_per_frame']:.0f} against {tn['ms_per_frame']:.0f} ms), "
            + ("and newton's cloth crosses itself ("
               + ", ".join(f"{k} pairs at frame {f}" for f, k in crossed) + ")"
               if crossed else "and neither crosses itself")
            + f" while rustcloth's has none at any checkpoint. Against the target of "
            f"{TWIST_TARGET_MS} ms a frame it is {t2['ms_per_frame'] / TWIST_TARGET_MS:.0f}x "
            "over on two threads"
            + (f"; self-collision is {sc:.0f} ms of it" if sc else "") + ".")
        mean_n, mean_r = tn["samples"][-1]["mean_stretch"], t2["samples"][-1]["mean_stretch"]
        max_n = max(s["max_stretch"] for s in tn["samples"])
        max_r = max(s["max_stretch"] for s in t2["samples"])
        text.append(
            f"- **Stretch.** The mean edge stretch is alike ({100 * mean_n:.1f} % in newton, "
            f"{100 * mean_r:.1f} % in rustcloth at the last checkpoint), so the materials "
            f"match on average; the largest is not: {max_n:.2f} in newton, {max_r:.2f} in "
            "rustcloth"
            + (", a few of whose edges are stretched far where the wound layers hold them "
               "(not examined further here)." if max_r > max_n else "."))
    f1, f2 = r.get("twist-rustcloth-fast-1"), r.get("twist-rustcloth-fast-2")
    if tn and f1 and f2 and not any("error" in v for v in (tn, f1, f2)):
        max_n = max(s["max_stretch"] for s in tn["samples"])
        text.append(
            f"- **The twist as the scenes step it** (2 steps a frame, the pairs ahead held "
            f"inside the solve): thread for thread rustcloth's frame is "
            f"{tn['ms_per_frame'] / f1['ms_per_frame']:.1f}x faster than newton's "
            f"({f1['ms_per_frame']:.0f} against {tn['ms_per_frame']:.0f} ms); on two threads "
            f"{f2['ms_per_frame']:.1f} ms, {f2['ms_per_frame'] / TWIST_TARGET_MS:.1f}x the "
            f"target; its largest stretch {max(s['max_stretch'] for s in f2['samples']):.2f} "
            f"(newton {max_n:.2f}).")
    if mn and m1 and m2 and not any("error" in v for v in (mn, m1, m2)):
        text.append(
            f"- **Mesh contact.** rustcloth's collider pass is "
            f"{mn['collide_ms_per_substep'] / m1['collide_ms_per_substep']:.1f}x faster than "
            f"newton's `collide` thread for thread ({m1['collide_ms_per_substep']:.2f} against "
            f"{mn['collide_ms_per_substep']:.2f} ms a substep) and "
            f"{m2['collide_ms_per_substep'] / MESH_TARGET_MS:.1f}x the target on two threads.")
    return text


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--only", nargs="*", default=None, help="run only these keys")
    args = p.parse_args()
    data = json.loads(RESULTS.read_text()) if RESULTS.exists() else {"results": {}}
    if not args.report_only:
        # The last commit that changed rustcloth itself (what setup.sh built), not this harness.
        commit = subprocess.run(
            ["git", "log", "-1", "--format=%h", "--", "src", "python", "Cargo.toml",
             "Cargo.lock", "pyproject.toml"],
            capture_output=True, text=True, cwd=str(ROOT)).stdout.strip()
        data.update(date=dt.date.today().isoformat(), commit=commit,
                    machine=f"{platform.processor() or platform.machine()}, "
                            f"{os.cpu_count()} cores, no GPU")
        for run in runs(args.quick):
            if args.only and run["key"] not in args.only:
                continue
            print(f"{run['key']:<20}", end=" ", flush=True)
            result = execute(run)
            result.update(date=data["date"], commit=data["commit"])
            data["results"][run["key"]] = result
            print(result.get("error") or {k: result.get(k) for k in (
                "ms_per_frame", "collide_ms_per_substep", "setup_s", "load") if k in result},
                flush=True)
            RESULTS.write_text(json.dumps(data, indent=1) + "\n")
    DOC.write_text(report(data))
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
