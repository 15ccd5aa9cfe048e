//! The built-in garments sewn on the mannequin: time per 1/60 s frame while the seams close
//! and once the garment is at rest, on 2 threads and 1, with self-collision (as the scenes
//! have it) and without; where the time goes (each pass of `Simulation::profile`, each stage of
//! the self-collision pass); and the state every half second of the first configuration
//! (largest seam gap, kinetic energy, lowest vertex; none is checked here, `tests/garment.rs`
//! does that independently). The configurations run in lock-step, each frame stepped in every
//! one in turn, so that the load of a shared machine falls on all of them alike and their
//! ratios mean something.
//!
//! `cargo run --release --example garment_bench -- [SCENES] [SECONDS] [THREADS] [SUBSTEPS]`:
//! SCENES comma-separated (default `shirt,skirt`), SECONDS simulated (default 3: the shirt's
//! seams close by 1.5 s and it rests from about 2.5 s), THREADS comma-separated (default
//! `2,1`), SUBSTEPS comma-separated (default the scene's own; `5,6` also runs each
//! configuration at 6). About two minutes on two shared cores with the defaults.

use std::time::Instant;

use rayon::ThreadPool;
use rustcloth::{Scene, Simulation};

/// Frames of 1/60 s.
const FRAME: f64 = 1.0 / 60.0;

fn list(arg: Option<&String>) -> Option<Vec<usize>> {
    arg.map(|s| s.split(',').map(|t| t.parse().expect("a count")).collect())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scenes = args.get(1).map_or("shirt,skirt", String::as_str);
    let seconds: f64 = args.get(2).map_or(3.0, |s| s.parse().expect("SECONDS"));
    let threads = list(args.get(3)).unwrap_or(vec![2, 1]);
    let pools: Vec<ThreadPool> = threads
        .iter()
        .map(|&t| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .expect("a pool")
        })
        .collect();
    for name in scenes.split(',') {
        let scene = Scene::builtin(name).expect("a built-in garment");
        let sewn = scene.sewn().expect("the garment compiles");
        let mesh = sewn.cloth.mesh.as_ref().expect("a garment is a mesh cloth");
        let seams = mesh.seams.as_ref().expect("a garment has seams");
        println!(
            "\n{name}: {} vertices, {} triangles, {} seam pairs, sewn over {} s, dt {} s x {} \
             substeps, self-collision thickness {} m",
            mesh.vertices.len(),
            mesh.triangles.len(),
            seams.pairs.len(),
            seams.sew_time,
            scene.dt,
            scene.substeps,
            scene.self_collision.as_ref().map_or(0.0, |s| s.thickness),
        );
        let substeps = list(args.get(4)).unwrap_or(vec![scene.substeps as usize]);
        let mut configs = Vec::new();
        for &n in &substeps {
            for (pool, &t) in pools.iter().zip(&threads) {
                for collide in [true, false] {
                    let mut scene = scene.clone();
                    scene.substeps = n as u32;
                    if !collide {
                        scene.self_collision = None;
                    }
                    let label = format!(
                        "{name}, {n} substeps, {t} thread(s), {}",
                        if collide {
                            "with self-collision"
                        } else {
                            "without self-collision"
                        }
                    );
                    configs.push((pool, label, collide, scene));
                }
            }
        }
        let runs = run(&configs, seconds, seams.sew_time);
        for ((_, label, collide, _), run) in configs.iter().zip(&runs) {
            run.print(label, *collide);
        }
    }
}

/// What one run measured: median ms per frame in each phase, and the time per pass and per
/// self-collision stage in each (ms per frame, from the simulation's own counters).
struct Run {
    sewing: Phase,
    resting: Phase,
}

#[derive(Default)]
struct Phase {
    frames: Vec<f64>,
    /// (pass, seconds) summed over the phase.
    passes: Vec<(&'static str, f64)>,
    /// Self-collision: search, repulsion, cap, redo seconds; substeps that used the swept
    /// search, and substeps.
    stages: [f64; 4],
    swept: u64,
    substeps: u64,
}

impl Phase {
    fn median(&self) -> f64 {
        let mut v = self.frames.clone();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    }

    fn per_frame(&self, seconds: f64) -> f64 {
        1e3 * seconds / self.frames.len().max(1) as f64
    }
}

/// The simulation's counters at one moment.
struct Counters {
    passes: Vec<(&'static str, f64)>,
    stages: [f64; 4],
    swept: u64,
    substeps: u64,
}

fn counters(sim: &Simulation) -> Counters {
    let passes = sim
        .profile()
        .passes()
        .iter()
        .map(|p| (p.name, p.time.as_secs_f64()))
        .collect();
    let sc = sim.self_collision_stats();
    Counters {
        passes,
        stages: sc.map_or([0.0; 4], |s| {
            [
                s.effort.search_seconds,
                s.effort.repulsion_seconds,
                s.effort.cap_seconds,
                s.effort.redo_seconds,
            ]
        }),
        swept: sc.map_or(0, |s| s.swept_substeps),
        substeps: sc.map_or(0, |s| s.substeps),
    }
}

/// Adds what the counters gained from `from` to `to` to `phase`.
fn gained(phase: &mut Phase, from: &Counters, to: &Counters) {
    for &(name, t) in &to.passes {
        let before = from
            .passes
            .iter()
            .find(|p| p.0 == name)
            .map_or(0.0, |p| p.1);
        match phase.passes.iter_mut().find(|p| p.0 == name) {
            Some(p) => p.1 += t - before,
            None => phase.passes.push((name, t - before)),
        }
    }
    for k in 0..4 {
        phase.stages[k] += to.stages[k] - from.stages[k];
    }
    phase.swept += to.swept - from.swept;
    phase.substeps += to.substeps - from.substeps;
}

/// Steps every configuration frame by frame in turn for `seconds`.
fn run(configs: &[(&ThreadPool, String, bool, Scene)], seconds: f64, sew_time: f64) -> Vec<Run> {
    let mut sims: Vec<Simulation> = configs
        .iter()
        .map(|c| Simulation::new(c.3.clone()).expect("the scene runs"))
        .collect();
    let mut runs: Vec<Run> = configs
        .iter()
        .map(|_| Run {
            sewing: Phase::default(),
            resting: Phase::default(),
        })
        .collect();
    let frames = (seconds / FRAME).round() as usize;
    println!(
        "   t (s)   gap (mm)   kinetic (J)   lowest (m)   ({})",
        configs[0].1
    );
    for frame in 1..=frames {
        for ((config, sim), run) in configs.iter().zip(&mut sims).zip(&mut runs) {
            let before = counters(sim);
            let clock = Instant::now();
            config
                .0
                .install(|| sim.advance(FRAME))
                .expect("no divergence");
            let ms = clock.elapsed().as_secs_f64() * 1e3;
            let t = sim.time();
            let phase = if t <= sew_time {
                Some(&mut run.sewing)
            } else if t > seconds - 1.0 {
                Some(&mut run.resting)
            } else {
                None
            };
            if let Some(phase) = phase {
                phase.frames.push(ms);
                gained(phase, &before, &counters(sim));
            }
        }
        if frame % 30 == 0 {
            let sim = &sims[0];
            let pos = sim.positions();
            let lowest = (0..pos.len())
                .map(|k| pos.get(k).y)
                .fold(f32::INFINITY, f32::min);
            println!(
                "   {:5.2}   {:8.3}   {:11.3e}   {lowest:10.3}",
                sim.time(),
                sim.seam_gap().unwrap_or(f32::NAN) * 1e3,
                sim.energy().kinetic
            );
        }
    }
    runs
}

impl Run {
    fn print(&self, label: &str, collide: bool) {
        println!(
            "{label}: median ms per 1/60 s frame {:.2} while sewing, {:.2} at rest (last 1 s)",
            self.sewing.median(),
            self.resting.median()
        );
        for (label, phase) in [("sewing", &self.sewing), ("at rest", &self.resting)] {
            let passes: Vec<String> = phase
                .passes
                .iter()
                .map(|&(n, s)| format!("{n} {:.2}", phase.per_frame(s)))
                .collect();
            print!(
                "    {label}, mean ms per frame by pass: {}",
                passes.join(", ")
            );
            if collide {
                let [search, repulsion, cap, redo] = phase.stages.map(|s| phase.per_frame(s));
                print!(
                    "; self-collision search {search:.2}, repulsion {repulsion:.2}, cap \
                     {cap:.2}, redo {redo:.2}, swept search in {} of {} substeps",
                    phase.swept, phase.substeps
                );
            }
            println!();
        }
    }
}
