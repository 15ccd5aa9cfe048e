//! The built-in garments sewn on the mannequin: time per 1/60 s frame while the seams close
//! and once the garment is at rest, and the state every half second (largest seam gap,
//! kinetic energy, lowest vertex, closest approach to the body's shapes by the solver's own
//! distance: none is checked here, `tests/garment.rs` does that independently).
//!
//! `cargo run --release --example garment_bench -- [SCENES] [SECONDS] [THREADS]`: SCENES
//! comma-separated (default `shirt,skirt`), SECONDS simulated (default 5), THREADS the rayon
//! pool (default 2). About a minute on two shared cores with the defaults.

use std::time::Instant;

use rustcloth::{Scene, Simulation};

/// Frames of 1/60 s.
const FRAME: f64 = 1.0 / 60.0;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scenes = args
        .get(1)
        .map_or("shirt,skirt", String::as_str)
        .to_string();
    let seconds: f64 = args.get(2).map_or(5.0, |s| s.parse().expect("SECONDS"));
    let threads: usize = args.get(3).map_or(2, |s| s.parse().expect("THREADS"));
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .expect("one global pool");
    for name in scenes.split(',') {
        run(name, seconds, threads);
    }
}

fn run(name: &str, seconds: f64, threads: usize) {
    let scene = Scene::builtin(name).expect("a built-in garment");
    let mesh = scene
        .cloth
        .mesh
        .as_ref()
        .expect("a garment is a mesh cloth");
    let seams = mesh.seams.as_ref().expect("a garment has seams");
    let (pairs, sew_time) = (seams.pairs.clone(), seams.sew_time);
    println!(
        "{name}: {} vertices, {} triangles, {} seam pairs, sewn over {sew_time} s, dt {} s x {} \
         substeps, {threads} threads",
        mesh.vertices.len(),
        mesh.triangles.len(),
        pairs.len(),
        scene.dt,
        scene.substeps
    );
    let mut sim = Simulation::new(scene).expect("the scene runs");
    let frames = (seconds / FRAME).round() as usize;
    let (mut sewing, mut resting) = (Vec::new(), Vec::new());
    println!("   t (s)   gap (mm)   kinetic (J)   lowest (m)");
    for frame in 1..=frames {
        let clock = Instant::now();
        sim.advance(FRAME).expect("no divergence");
        let ms = clock.elapsed().as_secs_f64() * 1e3;
        let t = sim.time();
        if t <= sew_time {
            sewing.push(ms);
        } else if t > seconds - 1.0 {
            resting.push(ms);
        }
        if frame % 30 == 0 {
            let pos = sim.positions();
            let p = |k: i64| pos.get(k as usize);
            let gap = pairs
                .iter()
                .map(|&[a, b]| p(a).distance(p(b)))
                .fold(0.0f32, f32::max);
            let lowest = (0..pos.len())
                .map(|k| pos.get(k).y)
                .fold(f32::INFINITY, f32::min);
            println!(
                "   {t:5.2}   {:8.3}   {:11.3e}   {lowest:10.3}",
                gap * 1e3,
                sim.energy().kinetic
            );
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "{name}: median ms per 1/60 s frame: {:.2} while sewing (first {sew_time} s), {:.2} at \
         rest (last 1 s)",
        median(&mut sewing),
        median(&mut resting)
    );
}
