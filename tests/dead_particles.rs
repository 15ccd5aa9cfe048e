//! A cut particle is absent from every computation: wherever it is and
//! however it moves, the live cloth evolves bitwise the same, with every integrator and every
//! optional pass.

use crate::common;

use common::{every_pass_scene, proptest_config, with_threads, Passes};
use glam::Vec3;
use proptest::prelude::*;
use proptest::sample::select;
use rustcloth::IntegratorKind;
use rustcloth::{Scene, Simulation};

/// A vertical cloth draping over a sphere onto a floor, with drag, strain limiting and the
/// watchdog's stretch check.
fn scene(nx: u32, ny: u32, integrator: IntegratorKind) -> Scene {
    let passes = Passes {
        floor: 0.55,
        sphere: ([0.1, 0.9, 0.05], 0.25),
        pins: "top_edge",
        max_stretch: 50.0,
    };
    every_pass_scene(nx, ny, integrator, passes)
}

/// Positions a cut particle may be moved to: far, at float32's edge, on a live neighbour.
const FAR: [f32; 7] = [1e30, -1e30, 3.0e38, -3.0e38, 1e-40, 0.0, 1.0];

/// The bits of every live particle's position and velocity.
fn live_bits(sim: &Simulation) -> Vec<u32> {
    let alive = &sim.particles().alive;
    let mut out = Vec::new();
    for v in [sim.positions(), sim.velocities()] {
        for c in [&v.x, &v.y, &v.z] {
            out.extend(
                c.iter()
                    .zip(alive)
                    .filter(|(_, &a)| a)
                    .map(|(x, _)| x.to_bits()),
            );
        }
    }
    out
}

/// Steps a cloth with `cut` particles cut twice: once leaving them where they were, once
/// after moving them to `far` values; the live particles must agree bit for bit, and so must
/// what is derived from them.
fn check(nx: u32, ny: u32, integrator: IntegratorKind, cut: &[usize], far: &[f32]) {
    let build = || {
        let mut sim = Simulation::new(scene(nx, ny, integrator)).unwrap();
        for &p in cut {
            sim.cut(p as i64).unwrap();
        }
        sim.step(3).unwrap();
        sim
    };
    let (mut still, mut moved) = (build(), build());
    let n = (nx * ny) as usize;
    let mut pos = moved.positions().clone();
    let mut vel = moved.velocities().clone();
    for (k, &p) in cut.iter().enumerate() {
        let f = far[k % far.len()];
        let g = far[(k + 3) % far.len()];
        pos.set(p, Vec3::new(f, g, -f));
        vel.set(p, Vec3::new(g, 5.0, f));
    }
    moved.set_positions(&pos).unwrap();
    moved.set_velocities(&vel).unwrap();
    // The same external change for the twin, so both integrators restart alike.
    still.set_positions(&still.positions().clone()).unwrap();
    still.set_velocities(&still.velocities().clone()).unwrap();
    // A cut particle that reached a computation spoils the live cloth on the first step after
    // the move (a NaN force, an infinite spring direction in the solve); a dozen steps also
    // carry the moved particle's velocity through the colliders' and strain limit's passes.
    let a = still.step(12).map(|()| live_bits(&still));
    let b = moved.step(12).map(|()| live_bits(&moved));
    match (&a, &b) {
        (Ok(a), Ok(b)) => assert!(
            a == b,
            "{integrator} {nx}x{ny}: a cut particle moved the live cloth (cut {cut:?})"
        ),
        _ => panic!(
            "{integrator} {nx}x{ny}: still {:?}, moved {:?}",
            a.as_ref().map(|_| "ok"),
            b.as_ref().map(|_| "ok")
        ),
    }
    assert_eq!(still.energy(), moved.energy(), "{integrator}: energy");
    assert_eq!(still.max_stretch(), moved.max_stretch(), "{integrator}");
    assert_eq!(still.triangles(), moved.triangles(), "{integrator}");
    let (na, nb) = (still.normals().clone(), moved.normals().clone());
    for p in (0..n).filter(|&p| still.particles().alive[p]) {
        assert_eq!(na.get(p), nb.get(p), "{integrator}: normal {p}");
    }
    let ray = (Vec3::new(0.0, 0.8, 5.0), Vec3::NEG_Z);
    assert_eq!(
        still.pick(ray.0, ray.1).unwrap(),
        moved.pick(ray.0, ray.1).unwrap()
    );
}

#[test]
fn a_cut_particle_moved_far_away_leaves_the_live_cloth_unchanged() {
    // A cut particle's springs were evaluated and multiplied by zero: moved to 1e30 m its
    // spring length overflowed, 0 * inf made the live neighbour's force NaN and the watchdog
    // blamed a live particle; with implicit Euler its infinite spring direction entered the
    // solve. Every integrator, one chunk and many.
    for integrator in IntegratorKind::ALL {
        check(12, 10, integrator, &[37, 38, 50], &FAR);
        with_threads(3, || {
            check(90, 60, integrator, &[2000, 2001, 4100, 5399], &FAR)
        });
    }
}

proptest! {
    #![proptest_config(proptest_config(24, 0xdead))]
    #[test]
    fn cut_particles_anywhere_leave_the_live_cloth_alone(
        integrator in select(IntegratorKind::ALL.to_vec()),
        (nx, ny) in (3u32..30, 3u32..30),
        cut_seeds in prop::collection::vec(0usize..10_000, 1..12),
        far in prop::collection::vec(select(&FAR[..]), 1..5),
    ) {
        let n = (nx * ny) as usize;
        // Never the top row: cutting every pin lets the cloth fall away from the sphere, which
        // is fine but checks less.
        let mut cut: Vec<usize> = cut_seeds.iter().map(|s| s % (n - nx as usize)).collect();
        cut.sort_unstable();
        cut.dedup();
        check(nx, ny, integrator, &cut, &far);
    }
}
