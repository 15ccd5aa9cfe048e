//! What a stroke cut costs (one segment: two rays, the quad between them, across the whole
//! cloth) at 128 x 128 and 512 x 512, the step after many cuts against an uncut cloth, and the
//! tearing pass (its scan of every spring, most steps tearing nothing, and a step that tears).
//! Each cut is made on a fresh copy so that every sample severs the same springs.
//!
//! `cargo run --release --example cut_budget`; the README's cutting section quotes its output.

use std::time::{Duration, Instant};

use glam::Vec3;
use rustcloth::{Scene, Simulation};

fn scene(n: u32) -> Scene {
    let mut scene = Scene::builtin("curtain").unwrap();
    // Still air: the costs quoted are of the cloth's own passes, as before it had a draught.
    scene.wind = None;
    scene.cloth.nx = n;
    scene.cloth.ny = n;
    scene
}

fn median(mut v: Vec<Duration>) -> f64 {
    v.sort();
    v[v.len() / 2].as_secs_f64() * 1e6
}

/// One stroke segment from the front across the cloth's middle, at height `y`.
fn segment(sim: &Simulation, y: f32) -> [(Vec3, Vec3); 2] {
    let pos = sim.positions();
    let z = (0..pos.len())
        .map(|p| pos.get(p).z)
        .fold(f32::MIN, f32::max)
        + 2.0;
    [
        (Vec3::new(-2.0, y, z), Vec3::NEG_Z),
        (Vec3::new(2.0, y, z), Vec3::NEG_Z),
    ]
}

fn main() {
    for n in [128, 512] {
        let base = Simulation::new(scene(n)).unwrap();
        let pos = base.positions();
        let (lo, hi) = (0..pos.len())
            .map(|p| pos.get(p).y)
            .fold((f32::MAX, f32::MIN), |(a, b), y| (a.min(y), b.max(y)));
        let mid = 0.5 * (lo + hi) + 0.25 * (hi - lo) / (n - 1) as f32;
        let samples = if n == 128 { 200 } else { 20 };
        let mut times = Vec::new();
        let mut severed = 0;
        for _ in 0..samples {
            let mut sim = Simulation::restore(base.snapshot()).unwrap();
            let rays = segment(&sim, mid);
            let start = Instant::now();
            severed = sim.sever_stroke(&rays).unwrap();
            times.push(start.elapsed());
        }
        println!(
            "{n} x {n}: one stroke segment across the cloth: {:.1} us median ({severed} springs)",
            median(times)
        );
        // The worst case for the row culling: a stroke down the cloth crosses every row.
        let mut times = Vec::new();
        for _ in 0..samples {
            let mut sim = Simulation::restore(base.snapshot()).unwrap();
            let z = 2.0
                + (0..pos.len())
                    .map(|p| pos.get(p).z)
                    .fold(f32::MIN, f32::max);
            let x = 0.25 * 1.5 / (n - 1) as f32;
            let rays = [
                (Vec3::new(x, hi + 1.0, z), Vec3::NEG_Z),
                (Vec3::new(x, lo - 1.0, z), Vec3::NEG_Z),
            ];
            let start = Instant::now();
            severed = sim.sever_stroke(&rays).unwrap();
            times.push(start.elapsed());
        }
        println!(
            "{n} x {n}: one stroke segment down the cloth: {:.1} us median ({severed} springs)",
            median(times)
        );
    }

    // The step after 40 cuts (40 horizontal strips) against the uncut cloth, interleaved.
    let n = 128;
    let mut uncut = Simulation::new(scene(n)).unwrap();
    let mut cut = Simulation::new(scene(n)).unwrap();
    for k in 0..40 {
        let y = 0.8 + 0.02 * k as f32 + 0.003;
        let rays = segment(&cut, y);
        cut.sever_stroke(&rays).unwrap();
    }
    let pieces = cut.pieces();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..300 {
        let start = Instant::now();
        uncut.step(1).unwrap();
        a.push(start.elapsed());
        let start = Instant::now();
        cut.step(1).unwrap();
        b.push(start.elapsed());
    }
    println!(
        "128 x 128 step: uncut {:.0} us, after 40 cuts ({pieces} pieces) {:.0} us (medians)",
        median(a),
        median(b)
    );

    // The tearing pass: per step, from the profile, on the tear scene at 128 and 512.
    for n in [128u32, 512] {
        let mut scene = Scene::builtin("tear").unwrap();
        scene.cloth.cuts.clear(); // the sheet uncut, as the cuts measured here find it
        scene.cloth.nx = n;
        scene.cloth.ny = n;
        scene.integrator = rustcloth::IntegratorKind::ImplicitEuler;
        scene.substeps = 1;
        let mut sim = Simulation::new(scene).unwrap();
        let steps = if n == 128 { 200 } else { 20 };
        sim.step(steps).unwrap();
        let pass = sim.profile().get("tearing").expect("the pass ran");
        println!(
            "{n} x {n}: tearing pass (nothing past the limit): {:.1} us per step, step {:.0} us",
            pass.time.as_secs_f64() * 1e6 / pass.calls as f64,
            sim.profile().total.as_secs_f64() * 1e6 / sim.profile().steps as f64,
        );
        // One tear: stretch the bottom-left corner far past the limit, then one step.
        let before = sim.topology_version();
        let p0 = sim.positions().get(0);
        sim.pin(0, Some(p0 + Vec3::new(-0.5, -0.5, 0.0))).unwrap();
        let calls = sim.profile().get("tearing").unwrap().calls;
        let time = sim.profile().get("tearing").unwrap().time;
        sim.step(1).unwrap();
        let after = sim.profile().get("tearing").unwrap();
        assert_eq!(after.calls, calls + 1);
        println!(
            "{n} x {n}: a step that tears ({} topology change): tearing pass {:.1} us",
            sim.topology_version() - before,
            (after.time - time).as_secs_f64() * 1e6
        );
    }
}
