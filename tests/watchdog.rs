//! The watchdog (src/watchdog.rs): trouble is caught before it reaches the state, rolled back to
//! a good state and reported, or saved by retrying the step with more substeps.

use crate::common;

use std::collections::HashMap;

use common::*;
use rustcloth::scene::{OnTrouble, PinSpec, WatchdogSpec};
use rustcloth::soa::Vec3s;
use rustcloth::{Error, Scene, Simulation, Trouble};

/// A hanging cloth whose springs are far too stiff for symplectic Euler at `dt` = 1 ms:
/// `h omega` = 4.5, where 2 is the stability limit. Four substeps hold it.
fn stiff_scene(watchdog: WatchdogSpec) -> Scene {
    let mut scene = scene_under_gravity(16, 16);
    scene.cloth.k_structural = 5000.0;
    scene.cloth.pins = vec![PinSpec::Named("top_corners".into())];
    scene.watchdog = watchdog;
    scene
}

fn limit(max_stretch: f64, on_trouble: OnTrouble) -> WatchdogSpec {
    WatchdogSpec {
        max_stretch: Some(max_stretch),
        on_trouble,
        ..WatchdogSpec::default()
    }
}

/// The largest `l / L` over the springs the scene simulates, in f32 as the watchdog computes it.
fn worst_stretch(sim: &Simulation) -> f32 {
    sim.max_stretch() + 1.0
}

/// Steps one at a time until a step fails; the error and the state hash after every step.
fn step_until_error(sim: &mut Simulation) -> (Error, HashMap<u64, u64>) {
    let mut history = HashMap::from([(0, state_hash(sim))]);
    loop {
        match sim.step(1) {
            Ok(()) => {
                history.insert(sim.steps(), state_hash(sim));
            }
            Err(e) => return (e, history),
        }
        assert!(sim.steps() < 1000, "the stiff cloth never went wrong");
    }
}

#[test]
fn stretch_beyond_the_limit_is_rolled_back_and_reported_before_any_nan() {
    let mut sim = Simulation::new(stiff_scene(limit(1.5, OnTrouble::Raise))).unwrap();
    let (err, history) = step_until_error(&mut sim);
    let Error::Diverged {
        step,
        particle,
        reason,
        substeps,
    } = err
    else {
        panic!("{err:?}")
    };
    let Trouble::Overstretched { stretch, limit } = reason else {
        panic!("{reason:?}")
    };
    assert!(stretch > 1.5 && stretch.is_finite(), "{stretch}");
    assert_eq!((limit, substeps), (1.5, 1));
    assert!(particle < sim.grid().len());
    // Found one step late (the next step's force loop judged the state), so the failed step
    // is undone too: the state is the one before `step`, bit for bit.
    assert_eq!(sim.steps(), step - 1);
    assert_eq!(state_hash(&sim), history[&(step - 1)]);
    assert!(worst_stretch(&sim) <= 1.5);
    assert_eq!(sim.watchdog_stats().caught, 1);
    // Stepping on redoes the undone step and fails the same way, back in the same state.
    assert_eq!(sim.step(2).unwrap_err(), err);
    assert_eq!(state_hash(&sim), history[&(step - 1)]);
}

#[test]
fn without_a_stretch_limit_the_same_cloth_only_stops_at_non_finite_values() {
    let mut sim = Simulation::new(stiff_scene(WatchdogSpec::default())).unwrap();
    let err = (0..1000).find_map(|_| sim.step(1).err()).unwrap();
    assert!(
        matches!(
            err,
            Error::Diverged {
                reason: Trouble::NonFinite,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn substep_retries_hold_the_stiff_cloth_and_are_counted() {
    let mut sim = Simulation::new(stiff_scene(limit(1.1, OnTrouble::Substep))).unwrap();
    for _ in 0..400 {
        sim.step(1).unwrap();
        assert!(sim.positions().x.iter().all(|x| x.is_finite()));
        assert!(worst_stretch(&sim) <= 1.1, "{}", worst_stretch(&sim));
    }
    assert_eq!(sim.steps(), 400);
    let stats = sim.watchdog_stats();
    assert!(
        stats.retried > 0 && stats.retried == stats.caught,
        "{stats:?}"
    );
    assert!((2..=64).contains(&stats.max_substeps_used), "{stats:?}");
    assert!(stats.retry_substeps >= 2 * stats.retried, "{stats:?}");
    // The rescued substeps are held, so the stiff cloth fails about once per hold_steps.
    assert!(stats.held_steps > 300 && stats.caught <= 8, "{stats:?}");
}

#[test]
fn without_holding_every_other_step_fails() {
    let mut watchdog = limit(1.1, OnTrouble::Substep);
    watchdog.hold_steps = 0;
    let mut sim = Simulation::new(stiff_scene(watchdog)).unwrap();
    sim.step(200).unwrap();
    let stats = sim.watchdog_stats();
    assert_eq!(stats.held_steps, 0);
    assert!(stats.caught > 20, "{stats:?}");
}

#[test]
fn retries_give_up_at_max_substeps_and_restore_the_state() {
    // Two substeps at most: not enough for h omega = 4.5.
    let mut watchdog = limit(1.5, OnTrouble::Substep);
    watchdog.max_substeps = 2;
    let mut sim = Simulation::new(stiff_scene(watchdog)).unwrap();
    let (err, history) = step_until_error(&mut sim);
    let Error::Diverged { step, substeps, .. } = err else {
        panic!("{err:?}")
    };
    assert_eq!(substeps, 2);
    assert_eq!(sim.steps(), step - 1);
    assert_eq!(state_hash(&sim), history[&(step - 1)]);
}

#[test]
fn a_limit_never_reached_changes_nothing() {
    // The check sits in the force loop: it must not change a single bit of the result.
    let mut calm = scene_under_gravity(24, 24);
    calm.cloth.pins = vec![PinSpec::Named("top_corners".into())];
    let mut plain = Simulation::new(calm.clone()).unwrap();
    calm.watchdog = limit(3.0, OnTrouble::Raise);
    let mut watched = Simulation::new(calm).unwrap();
    plain.step(300).unwrap();
    watched.step(300).unwrap();
    assert_eq!(state_hash(&plain), state_hash(&watched));
    assert_eq!(watched.watchdog_stats().caught, 0);
}

#[test]
fn a_state_set_beyond_the_limit_is_refused_not_stepped() {
    let mut scene = bare_scene(8, 8);
    scene.watchdog = limit(1.2, OnTrouble::Substep);
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(3).unwrap();
    let mut pos = sim.positions().clone();
    for x in pos.x.iter_mut() {
        *x *= 2.0;
    }
    sim.set_positions(&pos).unwrap();
    let before = (state_hash(&sim), sim.steps());
    // The user's state is not a step's fault: nothing to undo or retry.
    let err = sim.step(1).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Diverged {
                step: 4,
                reason: Trouble::Overstretched { .. },
                ..
            }
        ),
        "{err:?}"
    );
    assert_eq!((state_hash(&sim), sim.steps()), before);
}

#[test]
fn retried_stepping_is_bitwise_independent_of_the_thread_count() {
    // 120 x 100 particles: several chunks, whose length changes with the thread count.
    let mut scene = stiff_scene(limit(1.1, OnTrouble::Substep));
    scene.cloth.nx = 120;
    scene.cloth.ny = 100;
    scene.cloth.particle_mass = Some(0.001 * 16.0 * 16.0 / (120.0 * 100.0));
    scene.watchdog.max_substeps = 1024;
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = Simulation::new(scene.clone()).unwrap();
            // The first steps, while the cloth swings down from flat: the stiff springs need
            // the retries; settled, its corners hang past the limit for good.
            sim.step(60).unwrap();
            (state_hash(&sim), sim.watchdog_stats())
        })
    };
    let one = run(1);
    assert!(one.1.retried > 0);
    assert_eq!(one, run(2));
    assert_eq!(one, run(5));
}

#[test]
fn advance_counts_a_rolled_back_step() {
    // advance() keeps its time accounting when a failure also undoes the step before.
    let mut sim = Simulation::new(stiff_scene(limit(1.5, OnTrouble::Raise))).unwrap();
    let mut requested = 0.0;
    let err = loop {
        requested += 0.001;
        if let Err(e) = sim.advance(0.001) {
            break e;
        }
        assert!(sim.steps() < 1000);
    };
    let Error::Diverged { step, .. } = err else {
        panic!("{err:?}")
    };
    assert_eq!(sim.steps(), step - 1);
    // The time not simulated is still owed: exactly the failed step, which the check at the
    // end of the call caught before handing its state back.
    let owed = ((requested - sim.time()) / 0.001f64).round();
    assert_eq!(owed, 1.0);
}

#[test]
fn watchdog_memory_is_paid_only_with_a_stretch_limit() {
    let plain = Simulation::new(bare_scene(32, 32)).unwrap();
    let mut scene = bare_scene(32, 32);
    scene.watchdog = limit(2.0, OnTrouble::Raise);
    let watched = Simulation::new(scene).unwrap();
    let state_bytes = 2 * 3 * 4 * 32 * 32;
    assert_eq!(
        watched.memory_bytes() - plain.memory_bytes(),
        state_bytes,
        "one extra state buffer"
    );
}

#[test]
fn non_finite_input_is_still_rejected_before_the_watchdog_sees_it() {
    let mut scene = bare_scene(4, 4);
    scene.watchdog = limit(2.0, OnTrouble::Substep);
    let mut sim = Simulation::new(scene).unwrap();
    let mut pos = Vec3s::zeros(16);
    pos.x[3] = f32::NAN;
    assert!(sim.set_positions(&pos).is_err());
    sim.step(5).unwrap();
}

/// A landing at a long implicit step whose solve is halved for its energy rise (each half
/// evaluating forces from its own start): the stretch watch must judge the substep's start state
/// only, as the scan that names the spring does, or a retried step fails as an internal error.
#[test]
fn a_halved_implicit_solve_judges_stretch_at_the_substep_start() {
    let scene = Scene::from_toml_str(
        r#"
        integrator = "implicit_euler"
        dt = 0.016666666666666666
        air_drag = 0.0
        cg_max_iterations = 1
        preconditioner = "jacobi"
        [cloth]
        nx = 3
        ny = 2
        size = [0.1, 1.9544695484155405]
        center = [0.0, 0.0, 0.0]
        plane = "xy"
        k_structural = 277.8424760521764
        k_shear = 11.84448999515455
        k_bend = 12.638599851346797
        damping = 0.03128773994491654
        pins = ["top_corners", [0, 1]]
        [floor]
        height = -0.43122327812880995
        friction = 0.24808397053681805
        thickness = 0.007015799180520596
        [watchdog]
        max_stretch = 2.3711132326209152
        on_trouble = "substep"
        max_substeps = 8
        "#,
    )
    .unwrap();
    let mut sim = Simulation::new(scene).unwrap();
    match sim.step(6) {
        Ok(()) | Err(Error::Diverged { .. }) => {}
        Err(other) => panic!("a step failed as {other}"),
    }
}
