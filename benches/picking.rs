//! Picking through the BVH against a brute-force scan, at 1k, 16k, 65k and 262k particles:
//! building the tree, refitting it after the cloth moved, one query, and a whole cut stroke.
//!
//! `cargo bench --bench picking`; the table is in docs/picking.md.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use glam::Vec3;
use rustcloth::picking::PickStrategy;
use rustcloth::picking::{
    pick_particle_brute_force, pick_particle_scan, pick_triangle_brute_force, pick_triangle_scan,
    ParticleBvh, Ray, TriangleBvh,
};
use rustcloth::soa::Vec3s;
use rustcloth::{Scene, Simulation};

const SIDES: [u32; 4] = [32, 128, 256, 512];

/// An `n` x `n` cloth of 1 m in the xz plane at y = 1, draped into a wave of 5 cm so that the
/// tree is not trivially flat.
fn cloth(n: u32) -> Simulation {
    let mut scene = Scene::default();
    scene.cloth.nx = n;
    scene.cloth.ny = n;
    let mut sim = Simulation::new(scene).unwrap();
    let pos = wavy(sim.positions(), 0.0);
    sim.set_positions(&pos).unwrap();
    sim
}

fn wavy(pos: &Vec3s, phase: f32) -> Vec3s {
    Vec3s::from_fn(pos.len(), |p| {
        let x = pos.get(p);
        Vec3::new(
            x.x,
            1.0 + 0.05 * (6.0 * x.x + phase).sin() * (5.0 * x.z).cos(),
            x.z,
        )
    })
}

/// Rays from a camera 1.5 m above and in front of the cloth, at points spread over it: each
/// hits the cloth.
fn rays(count: usize) -> Vec<Ray> {
    let eye = Vec3::new(0.0, 2.5, 1.5);
    (0..count)
        .map(|k| {
            let s = k as f32 / count as f32;
            let at = Vec3::new(0.8 * s - 0.4, 1.0, 0.3 * (13.0 * s).sin());
            Ray::new(eye, at - eye).unwrap()
        })
        .collect()
}

fn quick(c: &mut Criterion) -> criterion::BenchmarkGroup<'_, criterion::measurement::WallTime> {
    let mut group = c.benchmark_group("picking");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(20);
    group
}

fn bench_particles(c: &mut Criterion) {
    let mut group = quick(c);
    for n in SIDES {
        let sim = cloth(n);
        let id = |what: &str| BenchmarkId::new(what, n * n);
        let (pos, alive, r) = (sim.positions(), &sim.particles().alive, sim.pick_radius());
        let rays = rays(64);
        group.bench_function(id("particle_build"), |b| {
            b.iter(|| ParticleBvh::build(pos, alive, r))
        });
        let mut tree = ParticleBvh::build(pos, alive, r);
        let moved = wavy(pos, 0.5);
        group.bench_function(id("particle_refit"), |b| b.iter(|| tree.refit(&moved, r)));
        tree.refit(pos, r);
        let mut k = 0;
        group.bench_function(id("particle_query_bvh"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                tree.cast(&rays[k], pos)
            })
        });
        group.bench_function(id("particle_query_brute_force"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                pick_particle_brute_force(&rays[k], pos, alive, r)
            })
        });
        group.bench_function(id("particle_query_scan"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                pick_particle_scan(&rays[k], pos, alive, r)
            })
        });
    }
    group.finish();
}

fn bench_triangles(c: &mut Criterion) {
    let mut group = quick(c);
    for n in SIDES {
        let mut sim = cloth(n);
        let id = |what: &str| BenchmarkId::new(what, n * n);
        let tris = sim.triangles().to_vec();
        let (grid, pos, alive) = (sim.grid(), sim.positions(), &sim.particles().alive);
        let rays = rays(64);
        group.bench_function(id("triangle_build"), |b| {
            b.iter(|| TriangleBvh::build(grid, pos, alive))
        });
        let mut tree = TriangleBvh::build(grid, pos, alive);
        let moved = wavy(pos, 0.5);
        group.bench_function(id("triangle_refit"), |b| b.iter(|| tree.refit(&moved)));
        tree.refit(pos);
        let mut k = 0;
        group.bench_function(id("triangle_query_bvh"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                tree.cast(&rays[k], pos)
            })
        });
        group.bench_function(id("triangle_query_brute_force"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                pick_triangle_brute_force(&rays[k], pos, &tris)
            })
        });
        group.bench_function(id("triangle_query_scan"), |b| {
            b.iter(|| {
                k = (k + 1) % rays.len();
                pick_triangle_scan(&rays[k], grid, pos, alive)
            })
        });
    }
    group.finish();
}

/// What the demo does per frame: the cloth moved since the last frame, then one pick (or a
/// stroke of 64 rays cutting what they hit), through the Simulation API with its lazy trees.
fn bench_frames(c: &mut Criterion) {
    let mut group = quick(c);
    for n in SIDES {
        let id = |what: &str| BenchmarkId::new(what, n * n);
        let rays = rays(64);
        let stroke: Vec<(Vec3, Vec3)> = rays.iter().map(|r| (r.origin, r.dir)).collect();
        let mut sim = cloth(n);
        sim.set_pick_strategy(PickStrategy::Bvh);
        sim.pick(stroke[0].0, stroke[0].1).unwrap(); // the tree exists
        let pos = [wavy(sim.positions(), 0.5), wavy(sim.positions(), 0.0)];
        let mut k = 0;
        // Includes the O(n) copy of set_positions, timed alone below.
        for strategy in [PickStrategy::Auto, PickStrategy::Bvh] {
            sim.set_pick_strategy(strategy);
            let name = format!("moved_then_one_pick_{}", strategy.name());
            group.bench_function(id(&name), |b| {
                b.iter(|| {
                    k += 1;
                    sim.set_positions(&pos[k % 2]).unwrap();
                    sim.pick(stroke[k % 64].0, stroke[k % 64].1).unwrap()
                })
            });
        }
        group.bench_function(id("set_positions_only"), |b| {
            b.iter(|| {
                k += 1;
                sim.set_positions(&pos[k % 2]).unwrap()
            })
        });
        group.bench_function(id("moved_then_stroke_of_64_cuts"), |b| {
            b.iter_batched(
                || {
                    let mut sim = cloth(n);
                    sim.set_pick_strategy(PickStrategy::Bvh);
                    sim.pick(stroke[0].0, stroke[0].1).unwrap(); // the tree exists
                    sim.set_pick_strategy(PickStrategy::Auto);
                    sim.set_positions(&pos[0]).unwrap(); // and the cloth moved
                    sim
                },
                |mut sim| {
                    let cut = sim.cut_stroke(&stroke).unwrap();
                    (sim, cut)
                },
                BatchSize::PerIteration,
            )
        });
        group.bench_function(id("stroke_of_64_brute_force_cuts"), |b| {
            b.iter_batched(
                || cloth(n),
                |mut sim| {
                    for ray in &rays {
                        let alive = &sim.particles().alive;
                        let r = sim.pick_radius();
                        if let Some(hit) = pick_particle_brute_force(ray, sim.positions(), alive, r)
                        {
                            sim.cut(hit.index as i64).unwrap();
                        }
                    }
                    sim
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench_particles, bench_triangles, bench_frames);
criterion_main!(benches);
