//! Grid shapes x thread counts: every integrator with every optional pass
//! steps any valid grid on any number of threads without a panic, and bitwise the same as on
//! one thread.
//!
//! The parallel passes cut the particle range into chunks of at least 2,048 particles and
//! blocks of at most 4,096, while a spring's index offset grows with the grid's width (a
//! bending spring spans `2 nx`). Wide grids, and any grid on many threads (whose chunks are
//! short), make blocks shorter than the offsets: the case a 1025 x 2 cloth hit on every step
//! and a 1500 x 64 cloth on 16 threads only. The shapes below put the offsets on both sides of
//! the chunk and block lengths; the property adds random wide and tall shapes.

use crate::common;

use common::{every_pass_scene, proptest_config, state_hash, with_threads, Passes};
use glam::Vec3;
use proptest::prelude::*;
use rustcloth::IntegratorKind;
use rustcloth::{Scene, Simulation};

/// Thread counts to compare: 16 makes every chunk the shortest (2,048 particles) on grids of
/// up to 128k particles.
const THREADS: [usize; 4] = [1, 2, 7, 16];

/// A vertical cloth of `nx` x `ny` with every optional pass the scene can ask for: drag, a
/// floor and a sphere it touches, strain limiting, the watchdog's stretch check.
fn scene(nx: u32, ny: u32, integrator: IntegratorKind) -> Scene {
    let passes = Passes {
        floor: 0.6,
        sphere: ([0.0, 1.0, 0.0], 0.2),
        pins: "top_corners",
        max_stretch: 10.0,
    };
    let mut scene = every_pass_scene(nx, ny, integrator, passes);
    scene.cloth.size = [2.0, 0.8];
    scene
}

/// Two steps with a kinematic pin dragged and a particle cut: every pass runs.
fn run(nx: u32, ny: u32, integrator: IntegratorKind) -> Result<u64, String> {
    let mut sim = Simulation::new(scene(nx, ny, integrator)).map_err(|e| e.to_string())?;
    sim.pin(0, Some(Vec3::new(-1.1, 0.5, 0.05))).unwrap();
    sim.cut((nx * ny / 2) as i64).unwrap();
    sim.step(2).map_err(|e| e.to_string())?;
    Ok(state_hash(&sim))
}

/// Runs every integrator on every thread count; the hashes must agree with one thread's.
fn check_shape(nx: u32, ny: u32) -> Result<(), TestCaseError> {
    check_shape_on(nx, ny, &THREADS)
}

/// [`check_shape`] on the thread counts `threads`, the first of them the reference.
fn check_shape_on(nx: u32, ny: u32, threads: &[usize]) -> Result<(), TestCaseError> {
    for integrator in IntegratorKind::ALL {
        let mut first = None;
        for &threads in threads {
            let outcome =
                std::panic::catch_unwind(|| with_threads(threads, || run(nx, ny, integrator)));
            let hash = outcome.map_err(|_| {
                TestCaseError::fail(format!(
                    "{nx} x {ny}, {integrator}, {threads} threads: panicked"
                ))
            })?;
            match &first {
                None => first = Some(hash),
                Some(expected) => prop_assert_eq!(
                    expected,
                    &hash,
                    "{} x {}, {}: {} threads differ from 1",
                    nx,
                    ny,
                    integrator,
                    threads
                ),
            }
        }
    }
    Ok(())
}

#[test]
fn wide_grids_step_through_the_force_pass() {
    // A 1025 x 2 cloth validated, then every step panicked: its bending springs' offset
    // (2 nx = 2050) passed the end of the first 2,048-particle chunk, and the fused force pass
    // took the part of the chunk before that offset as an edge region reaching past the chunk.
    // Any nx >= 2049 did the same, and 1500 x 64 only on 16 threads, whose chunks are shortest.
    for (nx, ny) in [(1025, 2), (2049, 2)] {
        check_shape(nx, ny).unwrap();
    }
    // 1500 x 64 on the count that panicked and one thread only: at 96k particles it costs more
    // than every other shape here together, and the shapes around it compare 2 and 7 threads.
    check_shape_on(1500, 64, &[1, 16]).unwrap();
}

#[test]
fn shapes_around_the_chunk_and_block_lengths() {
    let shapes = [
        (2, 2),
        (1024, 2),
        (1023, 3),
        (2047, 2),
        (2048, 2),
        (4095, 2),
        (4097, 2),
        (2, 4097),
        (3, 1400),
        (683, 6),
        (1366, 3),
        (2050, 3),
    ];
    for (nx, ny) in shapes {
        check_shape(nx, ny).unwrap();
    }
}

/// Wide (up to 6,000 across) and tall (up to 6,000 down) grids of at most 40k particles.
fn shape() -> impl Strategy<Value = (u32, u32)> {
    prop_oneof![
        (2u32..6000, 2u32..7),
        (2u32..7, 2u32..6000),
        (2u32..400, 2u32..100),
    ]
}

proptest! {
    #![proptest_config(proptest_config(12, 0x5a9e5))]
    #[test]
    fn any_shape_on_any_thread_count((nx, ny) in shape()) {
        check_shape(nx, ny)?;
    }
}
