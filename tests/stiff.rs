//! The implicit solvers on stiff cloth at a display frame's step: each converges,
//! the preconditioner changes the answer only within the tolerance, both are deterministic for
//! any number of threads, cut particles take no part, and no state survives between steps.

use crate::common;

use common::*;
use glam::Vec3;
use rustcloth::integrators::{IntegratorKind, Preconditioner};
use rustcloth::scene::{ClothSpec, OnTrouble, PinSpec, Plane, SphereSpec, WatchdogSpec};
use rustcloth::soa::Vec3s;
use rustcloth::{Scene, Simulation};

/// A square metre of heavy cloth (0.5 kg) hung by two corners of its horizontal start, at
/// 1/60 s: `k_structural dt^2 / m` is `500 / 3600 / (0.5 / n^2)`, 160 at 24 x 24 and 4600 at
/// 128 x 128 (the benchmark scene of docs/stiff.md at a test's size).
fn stiff_drape(n: u32, integrator: IntegratorKind) -> Scene {
    Scene {
        integrator,
        dt: 1.0 / 60.0,
        cloth: ClothSpec {
            nx: n,
            ny: n,
            size: [1.0, 1.0],
            center: [0.0, 1.5, 0.0],
            plane: Plane::Xz,
            particle_mass: Some(0.5 / (n * n) as f64),
            k_structural: 500.0,
            k_shear: 125.0,
            k_bend: 25.0,
            damping: 0.01,
            pins: vec![PinSpec::Named("top_corners".into())],
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

fn finite_and_bounded(sim: &Simulation, bound: f32) {
    for p in 0..sim.grid().len() {
        let x = position(sim, p);
        assert!(
            x.is_finite() && x.abs().max_element() < bound,
            "particle {p} at {x}"
        );
    }
}

#[test]
fn the_stiff_scene_is_stiff() {
    let scene = stiff_drape(24, IntegratorKind::ImplicitEuler);
    let m = scene.particle_mass();
    assert!(scene.cloth.k_structural * scene.dt * scene.dt / m >= 100.0);
}

#[test]
fn each_preconditioner_converges_on_stiff_cloth_at_a_frame_step() {
    for preconditioner in Preconditioner::ALL {
        let mut scene = stiff_drape(24, IntegratorKind::ImplicitEuler);
        scene.preconditioner = preconditioner;
        scene.cg_max_iterations = 2000;
        let mut sim = Simulation::new(scene).unwrap();
        sim.step(45).unwrap();
        let stats = sim.solver_stats().unwrap();
        assert_eq!(stats.not_converged, 0, "{preconditioner}: {stats:?}");
        assert!(stats.last_residual <= 1e-4, "{preconditioner}: {stats:?}");
        finite_and_bounded(&sim, 3.0);
        assert!(
            sim.max_stretch() < 1.0,
            "{preconditioner}: {}",
            sim.max_stretch()
        );
        if preconditioner == Preconditioner::Multigrid {
            // The point of it: a handful of iterations where Jacobi needs a hundred.
            let mean = stats.iterations as f64 / stats.solves as f64;
            assert!(mean < 15.0, "multigrid took {mean} iterations per solve");
        }
    }
}

/// The stiff drape stepped 45 frames (0.75 s) by projective dynamics to a relative gradient
/// of 2e-2, with Chebyshev's `rho` (0: plain local-global iterations).
fn projective_drape(rho: f64) -> Simulation {
    let mut scene = stiff_drape(24, IntegratorKind::ProjectiveDynamics);
    scene.pd_iterations = 400;
    scene.pd_tolerance = 2e-2;
    scene.pd_chebyshev_rho = rho;
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(45).unwrap();
    sim
}

#[test]
fn projective_dynamics_converges_on_stiff_cloth_at_a_frame_step() {
    // Projective dynamics converges linearly and slowly on stiff cloth (its constant matrix is
    // far stiffer than the true Hessian across the springs): a relative gradient of 2e-2 takes
    // tens of iterations here, 1e-3 hundreds (docs/stiff.md).
    let sim = projective_drape(Scene::default().pd_chebyshev_rho);
    let stats = sim.solver_stats().unwrap();
    assert_eq!(stats.not_converged, 0, "{stats:?}");
    assert!(stats.last_residual <= 2e-2, "{stats:?}");
    assert_eq!(stats.factorizations, 1, "the matrix is factored once");
    finite_and_bounded(&sim, 3.0);
    assert!(sim.max_stretch() < 1.0, "{}", sim.max_stretch());
}

/// Chebyshev semi-iteration (Wang 2015) extrapolates the local-global iterates along their
/// slowly converging direction: with the default `rho = 0.8` the stiff drape reaches its
/// tolerance in about 36 iterations a step, against about 58 without (`rho = 0`). The golden
/// digest alone would not notice acceleration switched off (it is regenerated); the count does.
#[test]
fn chebyshev_acceleration_cuts_the_iterations_of_a_stiff_drape() {
    let mean = |sim: &Simulation| {
        let stats = sim.solver_stats().unwrap();
        assert_eq!(stats.not_converged, 0, "{stats:?}");
        stats.iterations as f64 / stats.solves as f64
    };
    let accelerated = mean(&projective_drape(Scene::default().pd_chebyshev_rho));
    let plain = mean(&projective_drape(0.0));
    assert!(
        accelerated < 45.0 && accelerated < 0.75 * plain,
        "{accelerated} iterations a step with Chebyshev, {plain} without"
    );
}

/// One step from a mid-drape state with `preconditioner` at `tolerance`: the new velocities.
fn one_step(preconditioner: Preconditioner, tolerance: f64, start: &Simulation) -> Vec3s {
    let mut scene = start.scene().clone();
    scene.preconditioner = preconditioner;
    scene.cg_tolerance = tolerance;
    scene.cg_max_iterations = 5000;
    let mut sim = Simulation::new(scene).unwrap();
    sim.set_positions(start.positions()).unwrap();
    sim.set_velocities(start.velocities()).unwrap();
    sim.step(1).unwrap();
    sim.velocities().clone()
}

fn relative_difference(a: &Vec3s, b: &Vec3s) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for p in 0..a.len() {
        diff += (a.get(p) - b.get(p)).length_squared() as f64;
        norm += b.get(p).length_squared() as f64;
    }
    (diff / norm).sqrt()
}

#[test]
fn the_preconditioner_changes_the_answer_only_within_the_tolerance() {
    let mut start = Simulation::new(stiff_drape(24, IntegratorKind::ImplicitEuler)).unwrap();
    start.step(20).unwrap();
    // A tight solve is the reference; every preconditioner's answer approaches it as the
    // tolerance tightens, and differs from it by about what the tolerance allows.
    let reference = one_step(Preconditioner::Multigrid, 1e-7, &start);
    for preconditioner in Preconditioner::ALL {
        let loose = relative_difference(&one_step(preconditioner, 1e-3, &start), &reference);
        let tight = relative_difference(&one_step(preconditioner, 1e-5, &start), &reference);
        assert!(loose < 2e-2, "{preconditioner} at 1e-3: {loose:e}");
        assert!(tight < 2e-4, "{preconditioner} at 1e-5: {tight:e}");
        assert!(tight < loose, "{preconditioner}: {tight:e} >= {loose:e}");
    }
}

#[test]
fn the_implicit_solvers_are_the_same_for_any_number_of_threads() {
    // 104 x 96 particles: several parallel chunks (2048 particles) and reduction chunks
    // (1024) whatever the thread count, and a grid with even and odd sides for the multigrid.
    for integrator in [
        IntegratorKind::ImplicitEuler,
        IntegratorKind::ProjectiveDynamics,
    ] {
        let mut scene = stiff_drape(96, integrator);
        scene.cloth.nx = 104;
        scene.pd_iterations = 6;
        scene.spheres = vec![SphereSpec {
            center: [0.1, 0.8, 0.0],
            ..SphereSpec::default()
        }];
        assert_bitwise_on_1_2_3_threads(&format!("{integrator}"), || {
            let mut sim = Simulation::new(scene.clone()).unwrap();
            sim.cut(sim.grid().index(50, 40) as i64).unwrap();
            sim.step(3).unwrap();
            state_hash(&sim)
        });
    }
}

/// A cut particle must take no part in any computation. Before the fix its
/// springs were evaluated and multiplied by zero: moved far away (which `set_positions`
/// allows, the position being finite), a spring's length overflowed to infinity and `0 * inf`
/// put NaN into its live neighbour's force and into implicit Euler's matrix, whose solve then
/// silently stopped at its first iteration.
#[test]
fn a_cut_particle_far_away_changes_nothing() {
    for integrator in IntegratorKind::ALL {
        let mut scene = stiff_drape(12, integrator);
        scene.dt = 1e-4;
        let build = |far: bool| {
            let mut sim = Simulation::new(scene.clone()).unwrap();
            sim.step(5).unwrap();
            let dead = sim.grid().index(5, 5);
            sim.cut(dead as i64).unwrap();
            // Both set the positions (which restarts Verlet's history), one moves the dead one.
            let mut pos = sim.positions().clone();
            if far {
                pos.set(dead, Vec3::splat(3e38));
            }
            sim.set_positions(&pos).unwrap();
            sim.step(20).unwrap();
            (sim, dead)
        };
        let ((near, dead), (far, _)) = (build(false), build(true));
        for p in (0..near.grid().len()).filter(|&p| p != dead) {
            assert_eq!(
                position(&near, p).to_array().map(f32::to_bits),
                position(&far, p).to_array().map(f32::to_bits),
                "{integrator}: particle {p}"
            );
        }
    }
}

/// The state an integrator keeps between steps must be rolled back when a
/// step is refused. Neither implicit solver keeps any (no warm start; the multigrid hierarchy is
/// rebuilt each step; projective dynamics' factorisation is a cache keyed on what it is built
/// from): a simulation put into a state by any history steps on exactly like a fresh one
/// given that state.
#[test]
fn the_implicit_solvers_keep_no_state_between_steps() {
    for integrator in [
        IntegratorKind::ImplicitEuler,
        IntegratorKind::ProjectiveDynamics,
    ] {
        let scene = stiff_drape(16, integrator);
        let mut lived = Simulation::new(scene.clone()).unwrap();
        lived.step(12).unwrap();
        lived.cut(40).unwrap();
        lived.step(3).unwrap();
        let mut fresh = Simulation::new(scene).unwrap();
        fresh.cut(40).unwrap();
        fresh.set_positions(lived.positions()).unwrap();
        fresh.set_velocities(lived.velocities()).unwrap();
        lived.step(5).unwrap();
        fresh.step(5).unwrap();
        assert_eq!(state_hash(&lived), state_hash(&fresh), "{integrator}");
    }
}

#[test]
fn projective_dynamics_follows_a_dragged_pin_and_its_watchdog_retries_substeps() {
    let mut scene = stiff_drape(16, IntegratorKind::ProjectiveDynamics);
    scene.watchdog = WatchdogSpec {
        max_stretch: Some(2.5),
        on_trouble: OnTrouble::Substep,
        ..WatchdogSpec::default()
    };
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(30).unwrap();
    // The middle of the top edge: not pinned before, so pinning it changes the matrix.
    let corner = sim.grid().index(8, 15);
    let start = position(&sim, corner);
    // A drag of 2 cm per frame: the cloth must follow, not tear or explode.
    for k in 1..=20 {
        let target = start + Vec3::new(0.02 * k as f32, 0.0, 0.0);
        sim.pin(corner as i64, Some(target)).unwrap();
        sim.step(1).unwrap();
        assert_eq!(position(&sim, corner), target);
    }
    finite_and_bounded(&sim, 4.0);
    let neighbour = position(&sim, corner + 1);
    assert!((neighbour - position(&sim, corner)).length() < 0.2);
    // Every factorisation follows a change of the pinned set: the first, then the pin.
    assert_eq!(sim.solver_stats().unwrap().factorizations, 2);
    // A snap of the pin across the room overstretches the springs; the watchdog's substeps
    // handle it or it raises, and either way no non-finite state is left.
    sim.pin(corner as i64, Some(start + Vec3::new(3.0, 0.0, 0.0)))
        .unwrap();
    let _ = sim.step(2);
    finite_and_bounded(&sim, 10.0);
}
