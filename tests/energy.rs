//! What users read off the state is reproducible: energy is bitwise the same
//! for any thread count and any repeated call, accumulated in f64, and finite for every finite
//! state.

use crate::common;

use common::{edge_first_pile, proptest_config, scene_under_gravity, with_threads};
use glam::Vec3;
use proptest::prelude::*;
use rustcloth::integrators::IntegratorKind;
use rustcloth::scene::{ColliderSpec, ShapeKind};
use rustcloth::soa::Vec3s;
use rustcloth::{Energy, Simulation};

fn bits(e: Energy) -> [u64; 3] {
    [
        e.kinetic.to_bits(),
        e.gravitational.to_bits(),
        e.elastic.to_bits(),
    ]
}

/// A cloth of `nx` x `ny` with positions and velocities scaled by `scale` (up to float32's
/// range, where a square no longer fits in float32).
fn sim_with(nx: u32, ny: u32, seed: u64, scale: f32) -> Simulation {
    let mut sim = Simulation::new(scene_under_gravity(nx, ny)).unwrap();
    let n = (nx * ny) as usize;
    let mut state = seed;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) - 0.5
    };
    let pos = Vec3s::from_fn(n, |_| Vec3::new(next(), next(), next()) * scale);
    let vel = Vec3s::from_fn(n, |_| Vec3::new(next(), next(), next()) * scale);
    sim.set_positions(&pos).unwrap();
    sim.set_velocities(&vel).unwrap();
    sim
}

#[test]
fn energy_is_the_same_for_any_thread_count_and_finite_at_huge_speeds() {
    // energy() summed with an adaptive parallel reduction, split wherever the scheduler
    // happened to: the same state gave different totals on 1, 2 or 7 threads and even between
    // two calls. And it squared float32 speeds in float32, so 1e20 m/s made it infinite.
    let sim = sim_with(150, 90, 1, 1.0);
    let reference = bits(with_threads(1, || sim.energy()));
    for threads in [1, 2, 3, 7, 16] {
        for _ in 0..3 {
            assert_eq!(bits(with_threads(threads, || sim.energy())), reference);
        }
    }
    let fast = sim_with(8, 8, 2, 1e20);
    let e = fast.energy();
    assert!(e.kinetic.is_finite() && e.kinetic > 1e36, "{e:?}");
    assert!(e.total().is_finite());
}

proptest! {
    #![proptest_config(proptest_config(24, 0xe4e7))]
    #[test]
    fn energy_is_reproducible_and_finite(
        (nx, ny) in (2u32..200, 2u32..120),
        seed in any::<u64>(),
        scale in prop::sample::select(vec![1e-30f32, 1.0, 1e10, 1e19, 3e38]),
        threads in 1usize..9,
    ) {
        let sim = sim_with(nx, ny, seed, scale);
        let one = with_threads(1, || sim.energy());
        let many = with_threads(threads, || sim.energy());
        prop_assert_eq!(bits(one), bits(many));
        prop_assert!(one.kinetic.is_finite() && one.gravitational.is_finite() && one.elastic.is_finite());
    }
}

/// The `pile` cloth dropped edge first onto the floor ([`edge_first_pile`], without its ball),
/// or onto a plane collider in its place, without self-collision, under `integrator` at one
/// substep of `dt`: asserts that its total energy never rises above its start (nothing does
/// work on the cloth) over `seconds`.
fn pile_never_gains_energy(integrator: IntegratorKind, dt: f64, seconds: f64) {
    for on_plane in [false, true] {
        let mut scene = edge_first_pile();
        scene.integrator = integrator;
        scene.dt = dt;
        scene.substeps = 1;
        scene.self_collision = None;
        scene.spheres.clear();
        if on_plane {
            let floor = scene.floor.take().unwrap();
            scene.colliders = vec![ColliderSpec {
                shape: ShapeKind::Plane,
                center: [0.0, floor.height, 0.0],
                friction: floor.friction,
                thickness: floor.thickness,
                ..ColliderSpec::default()
            }];
        }
        let mut sim = Simulation::new(scene).unwrap();
        let start = sim.energy().total();
        for step in 0..(seconds / dt).round() as usize {
            sim.step(1).unwrap();
            let e = sim.energy();
            assert!(
                e.total() <= start + 1e-3 * start.abs(),
                "{integrator} at {dt} s, plane {on_plane}: step {step}: {} J from {start} J \
                 ({e:?})",
                e.total()
            );
        }
    }
}

/// Implicit Euler at a display frame. Projecting the solve's result out of the floor afterwards
/// crushed the springs of rows that had landed on each other, and the dropped pile's total
/// energy rose from 6.53 J to 30.4 J (nearly all elastic). With the contacts held inside the
/// solve it never rises above its start.
#[test]
fn implicit_euler_contact_at_a_display_frame_adds_no_energy() {
    pile_never_gains_energy(IntegratorKind::ImplicitEuler, 1.0 / 60.0, 1.5);
}

/// Projective dynamics at a display frame and below: projected out of the floor after the
/// solve, the dropped pile rose from 6.53 J to about 35 J at 1/60 s. Each predicted contact is
/// a term of the solve's matrix now (`w_c/2 |x - P(x)|^2`), and the energy never rises.
#[test]
fn projective_dynamics_contact_at_a_display_frame_adds_no_energy() {
    for dt in [1.0 / 60.0, 1.0 / 120.0, 1.0 / 240.0] {
        pile_never_gains_energy(IntegratorKind::ProjectiveDynamics, dt, 1.5);
    }
}
