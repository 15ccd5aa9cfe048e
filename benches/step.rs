//! One simulation step at several cloth sizes, and what each optional effect costs.
//!
//! `cargo bench --bench step`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rustcloth::scene::{FloorSpec, SphereSpec};
use rustcloth::{Scene, Simulation};

fn scene(n: u32) -> Scene {
    let mut scene = Scene::default();
    scene.cloth.nx = n;
    scene.cloth.ny = n;
    scene
}

fn bench_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    for n in [64u32, 128, 256] {
        let mut sim = Simulation::new(scene(n)).unwrap();
        group.throughput(Throughput::Elements((n * n) as u64));
        group.bench_with_input(
            BenchmarkId::from_parameter(format!("{n}x{n}")),
            &n,
            |b, _| b.iter(|| sim.step(1).unwrap()),
        );
    }
    group.finish();
}

/// Each effect switched off in turn at 128x128: the saving a scene gets by not asking for it.
fn bench_effects(c: &mut Criterion) {
    let mut full = scene(128);
    full.air_drag = 0.001;
    full.floor = Some(FloorSpec::default());
    full.spheres = vec![SphereSpec::default()];
    let variants: Vec<(&str, Scene)> = vec![
        ("all", full.clone()),
        (
            "no_bend",
            Scene {
                cloth: rustcloth::scene::ClothSpec {
                    k_bend: 0.0,
                    ..full.cloth.clone()
                },
                ..full.clone()
            },
        ),
        (
            "no_shear",
            Scene {
                cloth: rustcloth::scene::ClothSpec {
                    k_shear: 0.0,
                    ..full.cloth.clone()
                },
                ..full.clone()
            },
        ),
        (
            "no_air_drag",
            Scene {
                air_drag: 0.0,
                ..full.clone()
            },
        ),
        (
            "no_gravity",
            Scene {
                gravity: [0.0; 3],
                ..full.clone()
            },
        ),
        (
            "no_floor",
            Scene {
                floor: None,
                ..full.clone()
            },
        ),
        (
            "no_spheres",
            Scene {
                spheres: vec![],
                ..full.clone()
            },
        ),
    ];
    let mut group = c.benchmark_group("effects_128");
    for (name, scene) in variants {
        let mut sim = Simulation::new(scene).unwrap();
        group.bench_function(name, |b| b.iter(|| sim.step(1).unwrap()));
    }
    group.finish();
}

/// One step of each integrator at 128x128. RK4 should cost about four force evaluations;
/// implicit Euler's cost is dominated by its CG iterations (printed after the group).
fn bench_integrators(c: &mut Criterion) {
    let mut group = c.benchmark_group("integrators_128");
    for integrator in rustcloth::IntegratorKind::ALL {
        let mut scene = scene(128);
        scene.integrator = integrator;
        // A step costs the same at any dt (but implicit Euler's CG iterations); keep each
        // integrator inside its stability limit so the state stays meaningful.
        if let Some(limit) = Simulation::new(scene.clone()).unwrap().stable_dt() {
            scene.dt = scene.dt.min(0.5 * limit);
        }
        let mut sim = Simulation::new(scene).unwrap();
        // Explicit Euler grows the undamped sideways swing of stretched springs even below its
        // stable dt, and criterion runs 1e5 steps and more: start over when it gives out.
        group.bench_function(integrator.name(), |b| {
            b.iter(|| {
                if sim.step(1).is_err() {
                    sim.reset().unwrap();
                }
            })
        });
        if let Some(stats) = sim.solver_stats() {
            println!(
                "{integrator}: {:.1} CG iterations per step (last residual {:.1e})",
                stats.iterations as f64 / stats.solves.max(1) as f64,
                stats.last_residual
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench_step, bench_effects, bench_integrators);
criterion_main!(benches);
