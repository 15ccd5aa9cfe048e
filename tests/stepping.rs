//! Stepping: fixed steps, frame-rate independence, determinism and divergence handling.

use crate::common;

use common::*;
use rustcloth::scene::{FloorSpec, SphereSpec};
use rustcloth::IntegratorKind;
use rustcloth::{Error, Scene, Simulation};

fn busy_scene(n: u32) -> Scene {
    let mut scene = hung_drape(n);
    scene.air_drag = 0.001;
    scene
}

#[test]
fn advancing_one_second_in_sixty_frames_or_in_one_call_gives_the_same_state() {
    let mut whole = Simulation::new(busy_scene(16)).unwrap();
    let mut frames = Simulation::new(busy_scene(16)).unwrap();
    let mut odd = Simulation::new(busy_scene(16)).unwrap();
    assert_eq!(whole.advance(1.0).unwrap(), 1000);
    let taken: u64 = (0..60).map(|_| frames.advance(1.0 / 60.0).unwrap()).sum();
    assert_eq!(taken, 1000);
    let mut left = 1.0;
    for frame in [0.0003, 0.0171, 0.25, 0.0005, 0.1, 0.3] {
        odd.advance(frame).unwrap();
        left -= frame;
    }
    odd.advance(left).unwrap();
    assert_eq!(whole.steps(), 1000);
    assert_eq!(state_hash(&whole), state_hash(&frames));
    assert_eq!(state_hash(&whole), state_hash(&odd));
    assert!((whole.time() - 1.0).abs() < 1e-12);
}

#[test]
fn the_state_is_bitwise_identical_for_any_number_of_threads() {
    // Grids of several parallel chunks (at least 2,048 particles each) whose chunk length
    // also changes with the thread count: a 40 x 40 cloth is one chunk on any number of
    // threads, and comparing thread counts on it compares nothing.
    for n in [100u32, 130] {
        let run = |threads| {
            with_threads(threads, || {
                let mut sim = Simulation::new(busy_scene(n)).unwrap();
                sim.step(60).unwrap();
                state_hash(&sim)
            })
        };
        let one = run(1);
        for threads in [2, 3, 4, 7] {
            assert_eq!(run(threads), one, "{n}x{n} with {threads} threads");
        }
    }
}

#[test]
fn repeated_runs_are_bitwise_identical() {
    let run = || {
        let mut sim = Simulation::new(busy_scene(64)).unwrap();
        sim.step(100).unwrap();
        state_hash(&sim)
    };
    assert_eq!(run(), run());
}

#[test]
fn a_diverging_step_is_rolled_back_and_reported() {
    for substeps in [1, 3] {
        let mut scene = Scene::builtin("hanging").unwrap();
        scene.cloth.k_structural = 1e7; // far past the explicit stability limit
        scene.substeps = substeps;
        let mut sim = Simulation::new(scene).unwrap();
        let mut last_good = (state_hash(&sim), sim.steps());
        let err = loop {
            match sim.step(1) {
                Ok(()) => last_good = (state_hash(&sim), sim.steps()),
                Err(e) => break e,
            }
            assert!(sim.steps() < 10_000, "never diverged");
        };
        let Error::Diverged { step, particle, .. } = err else {
            panic!("{err:?}")
        };
        assert_eq!(step, last_good.1 + 1);
        assert!(particle < sim.grid().len());
        assert_eq!(
            (state_hash(&sim), sim.steps()),
            last_good,
            "substeps {substeps}"
        );
        assert!(sim.positions().x.iter().all(|x| x.is_finite()));
    }
}

#[test]
fn switching_integrator_and_substeps_at_run_time() {
    let mut sim = Simulation::new(busy_scene(16)).unwrap();
    sim.step(10).unwrap();
    sim.set_integrator("explicit_euler").unwrap();
    sim.set_substeps(4).unwrap();
    sim.step(10).unwrap();
    assert!(sim.effects().contains(&"explicit_euler"));
    assert!(sim
        .set_integrator("leapfrog")
        .unwrap_err()
        .to_string()
        .contains("symplectic_euler"));
    assert!(sim.set_substeps(0).is_err());
    sim.reset().unwrap();
    assert_eq!(sim.steps(), 0);
    assert_eq!(sim.scene().integrator, IntegratorKind::ExplicitEuler);
}

#[test]
fn cutting_removes_springs_and_triangles() {
    let mut scene = busy_scene(8);
    scene.floor = Some(FloorSpec::default());
    scene.spheres = vec![SphereSpec::default()];
    let mut sim = Simulation::new(scene).unwrap();
    let before = sim.triangles().len();
    sim.cut(27).unwrap();
    sim.cut(27).unwrap(); // a second cut is a no-op
    assert_eq!(sim.topology_version(), 1);
    assert_eq!(sim.triangles().len(), before - 6);
    for kind in rustcloth::grid::SpringKind::ALL {
        sim.springs()
            .for_each(sim.grid(), kind, |a, b, _| assert!(a != 27 && b != 27));
    }
    for p in 0..64 {
        sim.cut(p).unwrap();
    }
    assert!(sim.triangles().is_empty());
    sim.step(10).unwrap();
    assert!(matches!(sim.cut(64), Err(Error::IndexOutOfRange { .. })));
}

#[test]
fn normals_are_unit_and_face_e_i_cross_e_j_on_a_flat_cloth() {
    let mut sim = Simulation::new(bare_scene(5, 4)).unwrap();
    let normals = sim.normals().clone();
    for p in 0..20 {
        // plane "xz": e_i x e_j = x x z = -y.
        assert!(
            (normals.get(p) - glam::Vec3::NEG_Y).length() < 1e-6,
            "{p}: {}",
            normals.get(p)
        );
    }
}
