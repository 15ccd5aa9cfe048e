//! A built-in garment on implicit Euler: solves and halved solves per step, and CPU time per
//! 1/60 s frame on one thread, while the seams close and once the garment is at rest. A
//! contact's friction decides whether the solve can hold the garment still without halving
//! its step (docs/garments.md, "On the implicit solvers"); `FRICTION` sets every collider's
//! and the floor's coefficient, to compare with frictionless contact.
//!
//! `cargo run --release --example garment_implicit -- [SCENE] [STEP] [SECONDS] [FRICTION]
//! [SELF]`: SCENE default `shirt`; STEP the implicit step in s (default 1/120); SECONDS
//! simulated (default 4); FRICTION (default, or `scene`: the scene's own); SELF `1` keeps the scene's
//! self-collision (default `0`, without). Runs on a one-thread pool; CPU time is the process's
//! (`/proc/self/task/*/schedstat`, ns), so other threads' work would count too.

use rustcloth::{IntegratorKind, Scene, Simulation};

/// Frames of 1/60 s.
const FRAME: f64 = 1.0 / 60.0;

/// CPU time of every thread of this process, s.
fn cpu_seconds() -> f64 {
    let tasks = std::fs::read_dir("/proc/self/task").expect("Linux /proc");
    tasks
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .sum::<u64>() as f64
        * 1e-9
}

/// Solves, halved solves and CPU seconds over a phase.
#[derive(Default)]
struct Phase {
    steps: u64,
    solves: u64,
    halved: u64,
    cpu: f64,
    frames: u64,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("shirt", String::as_str);
    let step: f64 = args
        .get(2)
        .map_or(1.0 / 120.0, |s| s.parse().expect("STEP"));
    let seconds: f64 = args.get(3).map_or(4.0, |s| s.parse().expect("SECONDS"));
    let friction: Option<f64> = (args.get(4))
        .filter(|s| *s != "scene")
        .map(|s| s.parse().expect("FRICTION"));
    let keep_self = args.get(5).is_some_and(|s| s == "1");
    let mut scene = Scene::builtin(name).expect("a built-in garment");
    scene.integrator = IntegratorKind::ImplicitEuler;
    scene.dt = step;
    scene.substeps = 1;
    if !keep_self {
        scene.self_collision = None;
    }
    if let Some(mu) = friction {
        scene.colliders.iter_mut().for_each(|c| c.friction = mu);
        scene.floor.iter_mut().for_each(|f| f.friction = mu);
    }
    let sew_time = scene
        .sewn()
        .expect("the garment compiles")
        .cloth
        .mesh
        .as_ref()
        .and_then(|m| m.seams.as_ref())
        .map_or(0.0, |s| s.sew_time);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool");
    let steps_per_frame = (FRAME / step).round().max(1.0) as u64;
    let frames = (seconds / FRAME).round() as u64;
    let mut sim = pool.install(|| Simulation::new(scene).expect("the scene builds"));
    // Sewing: up to the seams' close; at rest: the last second.
    let (mut sewing, mut rest) = (Phase::default(), Phase::default());
    for frame in 0..frames {
        let t = frame as f64 * FRAME;
        let before = sim.solver_stats().unwrap_or_default();
        let cpu = cpu_seconds();
        pool.install(|| sim.step(steps_per_frame)).expect("a step");
        let cpu = cpu_seconds() - cpu;
        let after = sim.solver_stats().unwrap_or_default();
        let phase = if t < sew_time {
            &mut sewing
        } else if t >= seconds - 1.0 {
            &mut rest
        } else {
            continue;
        };
        phase.steps += steps_per_frame;
        phase.solves += after.solves - before.solves;
        phase.halved += after.halved - before.halved;
        phase.cpu += cpu;
        phase.frames += 1;
    }
    let kinetic = sim.energy().kinetic;
    println!(
        "{name} on implicit Euler at {:.5} s, friction {}, self-collision {}: kinetic energy \
         at {seconds} s {kinetic:.2e} J",
        step,
        friction.map_or("the scene's".into(), |mu| mu.to_string()),
        if keep_self { "on" } else { "off" },
    );
    for (label, p) in [
        ("sewing (0 to sew_time)", &sewing),
        ("at rest (last 1 s)", &rest),
    ] {
        let steps = p.steps.max(1) as f64;
        println!(
            "  {label:>24}: {:.2} solves/step, {:.2} halved/step, {:.1} CPU ms/frame",
            p.solves as f64 / steps,
            p.halved as f64 / steps,
            1e3 * p.cpu / p.frames.max(1) as f64,
        );
    }
}
