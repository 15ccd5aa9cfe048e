//! What picking, dragging and cutting cost next to a step of a 128 x 128 cloth, measured in
//! one interleaved loop so that a busy machine slows both alike.
//!
//! `cargo run --release --example pick_budget`; docs/picking.md quotes its output.

use std::time::{Duration, Instant};

use glam::Vec3;
use rustcloth::{Scene, Simulation};

fn scene() -> Scene {
    let mut scene = Scene::default();
    scene.cloth.nx = 128;
    scene.cloth.ny = 128;
    scene
}

fn timed<R>(f: impl FnOnce() -> R) -> (R, Duration) {
    let start = Instant::now();
    let r = f();
    (r, start.elapsed())
}

fn median(mut v: Vec<Duration>) -> f64 {
    v.sort();
    v[v.len() / 2].as_secs_f64() * 1e6
}

/// 64 rays from a camera above the cloth, across its middle.
fn stroke() -> Vec<(Vec3, Vec3)> {
    let eye = Vec3::new(0.0, 2.5, 1.5);
    (0..64)
        .map(|k| {
            let at = Vec3::new(-0.4 + 0.8 * k as f32 / 63.0, 1.0, 0.0);
            (eye, at - eye)
        })
        .collect()
}

fn main() {
    let frames = 400;
    let mut sim = Simulation::new(scene()).unwrap();
    sim.step(50).unwrap();
    let eye = Vec3::new(0.0, 2.5, 1.5);
    let (mut step, mut pick, mut pick_tri, mut grab_drag) = (vec![], vec![], vec![], vec![]);
    let grabbed = sim.grid().index(64, 64);
    for frame in 0..frames {
        let ((), t) = timed(|| sim.step(1).unwrap());
        step.push(t);
        let at = sim.positions().get(grabbed);
        let (hit, t) = timed(|| sim.pick(eye, at - eye).unwrap());
        assert!(hit.is_some());
        pick.push(t);
        let (_, t) = timed(|| sim.pick_triangle(eye, at - eye).unwrap());
        pick_tri.push(t);
        let target = at + Vec3::new(0.0, 0.001 * (frame % 20) as f32, 0.0);
        let (_, t) = timed(|| {
            if frame == 0 {
                sim.grab(grabbed as i64).unwrap();
            }
            sim.drag_to(target).unwrap();
        });
        grab_drag.push(t);
    }
    let mut strokes = vec![];
    let mut cut = 0;
    for _ in 0..40 {
        let mut sim = Simulation::new(scene()).unwrap();
        let rays = stroke();
        sim.cut_stroke(&rays[..8]).unwrap(); // builds the tree
        sim.step(1).unwrap(); // the cloth moved: the stroke refits
        let (hits, t) = timed(|| sim.cut_stroke(&rays).unwrap());
        cut = hits.len();
        strokes.push(t);
    }
    let step = median(step);
    let report = |name: &str, us: f64| {
        println!(
            "{name:<34} {us:9.2} us  {:6.1}% of a step",
            100.0 * us / step
        );
    };
    println!(
        "128x128, {} threads, median of {frames} frames",
        rayon::current_num_threads()
    );
    report("step", step);
    report("pick (cloth moved: auto = scan)", median(pick));
    report("pick_triangle (auto = scan)", median(pick_tri));
    report("drag_to", median(grab_drag));
    report(
        &format!("cut_stroke, 64 rays ({cut} cuts)"),
        median(strokes),
    );
}
